//! The vocabulary the rooms' errors share to say what a failure is about, so that a front end
//! can tell the caller's usage mistakes (a malformed or contradictory request: a bad grid or
//! patch spec, an unknown kind, chart or shard, outputs that would collide, a LUT size out of
//! range) from failures of the data, the files or the device, and can name the parameter at
//! fault in its own spelling. Nothing here knows about flags, and nothing here knows the rooms:
//! each error type says for itself, beside its definition, whether it is a usage error (an
//! `is_usage` method) and, where it is about one parameter, which (a `concern` method returning a
//! [`Concern`]). Messages name parameters in words ("the exposure", "the corners").

/// A parameter of a request that an error can be about, named for what it is (the option
/// structs' fields), not for any front end's spelling of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Param {
    /// The most pixels a frame may have (`io::Limits::max_pixels`).
    MaxPixels,
    /// The EXR layer holding the camera RGB (`io::ReadOptions::layer`).
    Layer,
    /// A rendered chart's exposure (`chart::ChartOptions::exposure`).
    Exposure,
    /// A rendered chart's noise (`chart::ChartOptions::noise`).
    Noise,
    /// A rendered chart's patch size (`chart::ChartOptions::patch_size`).
    PatchSize,
    /// A rendered chart's gap between patches (`chart::ChartOptions::gap`).
    Gap,
    /// A rendered chart's columns (`chart::ChartOptions::columns`).
    Columns,
    /// The four corners of a photographed chart (`chart::ReadingOptions::corners`).
    Corners,
    /// The flat-field frame of a chart capture (`chart::FlatField::Frame`).
    Flat,
    /// The reference white of Lab reference values (`chart::Reference::load`).
    ReferenceWhite,
    /// The reflectance spectra of a chart (`chart::ChartColours::simulate`).
    Reflectances,
    /// A capture's white (clipping) level (`chart::ReadingOptions::white_level`).
    WhiteLevel,
    /// The neutral patch a fit takes its white from (`model::White::Patch`).
    WhitePatch,
}

/// How an error concerns a [`Param`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Concern {
    /// The value given for the parameter is malformed, out of range, or does not fit the data.
    Value(Param),
    /// The request failed without the parameter (or with its current value); giving it is the
    /// way out.
    Remedy(Param),
}

#[cfg(test)]
mod tests {
    /// The library's messages name no flag of the binary (`--layer`, `--corners`, …): a scan of
    /// every non-comment line of `src/` outside `src/cli` and `src/main.rs` (another program's
    /// flag, `sbatch --array`, is allowed).
    #[test]
    fn library_messages_name_no_flags() {
        fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
            for e in std::fs::read_dir(dir).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    if p.file_name().is_some_and(|n| n != "cli") {
                        walk(&p, out);
                    }
                } else if p.extension().is_some_and(|x| x == "rs")
                    && p.file_name().is_some_and(|n| n != "main.rs")
                    // A room's unit tests in their own file (`ocio_tests.rs`) run programs
                    // with flags; they print no library message.
                    && !p.file_stem().is_some_and(|s| s.to_string_lossy().ends_with("_tests"))
                {
                    out.push(p);
                }
            }
        }
        let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut files = Vec::new();
        walk(&src, &mut files);
        assert!(files.len() > 30, "{} files", files.len());
        let mut found = Vec::new();
        for f in &files {
            // A file's unit-test module (`mod tests {`, last in the file) holds no library message.
            let text = std::fs::read_to_string(f).unwrap();
            let lines = text.lines().take_while(|l| l.trim() != "mod tests {");
            for (i, line) in lines.enumerate() {
                let code = line.trim_start();
                if code.starts_with("//") || line.contains("sbatch --") {
                    continue;
                }
                let b = code.as_bytes();
                let flag = (0..b.len().saturating_sub(2)).any(|k| {
                    b[k] == b'-'
                        && b[k + 1] == b'-'
                        && b[k + 2].is_ascii_lowercase()
                        && (k == 0 || !(b[k - 1].is_ascii_alphanumeric() || b[k - 1] == b'-'))
                });
                if flag {
                    found.push(format!("{}:{}: {}", f.display(), i + 1, code));
                }
            }
        }
        assert!(
            found.is_empty(),
            "flag names in library code:\n{}",
            found.join("\n")
        );
    }
}
