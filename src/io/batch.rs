//! Batches: expanding command-line inputs into a sorted list of frames, slicing it for
//! `--shard`, and naming (and checking) outputs.

use super::{FileFormat, IoError};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// Whether a file name looks like a frame nsrm reads: `.exr`, `.tif`, `.tiff` (any case), not
/// hidden (so `._x.exr` AppleDouble files and nsrm's own `.x.tmp` files are left out).
pub fn is_frame_name(path: &Path) -> bool {
    let hidden = path
        .file_name()
        .and_then(|n| n.to_str())
        .is_none_or(|n| n.starts_with('.'));
    !hidden && FileFormat::from_extension(path).is_some()
}

fn has_glob_chars(s: &str) -> bool {
    s.contains(['*', '?', '['])
}

/// Expands inputs into a sorted, de-duplicated list of files:
/// * an existing file is taken as it is (its format is told by its content when read);
/// * a directory gives its EXR/TIFF files (not those of its subdirectories);
/// * anything else is a glob pattern (`shots/*.exr`, `plate.[0-9]*.tif`), whose matches are
///   filtered to EXR/TIFF file names.
///
/// An input that matches nothing is an error, naming it. Files reached twice (two patterns, or
/// `./a.exr` and `a.exr`) are listed once. The list is sorted by path, so every machine given
/// the same inputs sees the same order (see [`Shard`]).
pub fn expand_inputs<S: AsRef<str>>(specs: &[S]) -> Result<Vec<PathBuf>, IoError> {
    let mut found: Vec<PathBuf> = Vec::new();
    for spec in specs {
        let spec = spec.as_ref();
        let path = Path::new(spec);
        let before = found.len();
        if path.is_file() {
            found.push(path.to_path_buf());
            continue;
        }
        if path.is_dir() {
            let entries = std::fs::read_dir(path).map_err(|err| IoError::Read {
                path: path.to_path_buf(),
                err,
            })?;
            for e in entries {
                let e = e.map_err(|err| IoError::Read {
                    path: path.to_path_buf(),
                    err,
                })?;
                let p = e.path();
                if is_frame_name(&p) && p.is_file() {
                    found.push(p);
                }
            }
            if found.len() == before {
                return Err(IoError::NoMatch {
                    spec: spec.to_string(),
                    why: "the directory holds no .exr, .tif or .tiff files".into(),
                });
            }
            continue;
        }
        if !has_glob_chars(spec) {
            return Err(IoError::NoMatch {
                spec: spec.to_string(),
                why: "no such file or directory".into(),
            });
        }
        let paths = glob::glob(spec).map_err(|e| IoError::NoMatch {
            spec: spec.to_string(),
            why: format!("bad pattern: {e}"),
        })?;
        for p in paths {
            let p = p.map_err(|e| IoError::Read {
                path: e.path().to_path_buf(),
                err: std::io::Error::new(e.error().kind(), e.error().to_string()),
            })?;
            if is_frame_name(&p) && p.is_file() {
                found.push(p);
            }
        }
        if found.len() == before {
            return Err(IoError::NoMatch {
                spec: spec.to_string(),
                why: "the pattern matches no .exr, .tif or .tiff files".into(),
            });
        }
    }
    found.sort();
    let mut seen = HashSet::new();
    found.retain(|p| seen.insert(std::fs::canonicalize(p).unwrap_or_else(|_| p.clone())));
    Ok(found)
}

/// A deterministic slice of a batch: shard `index` of `count` (1-based, `1 ≤ index ≤ count`)
/// holds the inputs whose 0-based position `i` in the sorted list has `i % count == index - 1`.
/// The `count` shards are disjoint and together hold every input, so `count` machines given the
/// same inputs split the batch without talking to each other: a Slurm array `--array=1-N`
/// passes `--shard $SLURM_ARRAY_TASK_ID/N`; a Kubernetes indexed Job (indices from 0) passes
/// `--shard $((JOB_COMPLETION_INDEX + 1))/N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Parses `K/N` (1-based K).
    pub fn parse(spec: &str) -> Result<Shard, IoError> {
        let bad = |why: &str| IoError::Shard {
            spec: spec.to_string(),
            why: why.to_string(),
        };
        let (k, n) = spec
            .split_once('/')
            .ok_or_else(|| bad("expected K/N, e.g. 2/8 (K counts from 1)"))?;
        let k: usize = k
            .trim()
            .parse()
            .map_err(|_| bad("K is not a whole number"))?;
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| bad("N is not a whole number"))?;
        if n == 0 {
            return Err(bad("N must be at least 1"));
        }
        if k == 0 || k > n {
            return Err(bad(
                "K must be within 1..N (shards count from 1, like SLURM_ARRAY_TASK_ID with \
                 --array=1-N; for a 0-based index pass index+1)",
            ));
        }
        Ok(Shard { index: k, count: n })
    }

    /// Whether the input at 0-based position `i` belongs to this shard.
    pub fn contains(&self, i: usize) -> bool {
        i % self.count == self.index - 1
    }

    /// This shard's part of `items`, in order.
    pub fn select<T: Clone>(&self, items: &[T]) -> Vec<T> {
        items
            .iter()
            .enumerate()
            .filter(|(i, _)| self.contains(*i))
            .map(|(_, t)| t.clone())
            .collect()
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The output file for `input`: `<stem><suffix>.<ext>` in `out_dir`, or beside the input. A
/// frame number ending the stem stays at the end, so sequences stay sequences:
/// `plate.0101.exr` → `plate_xyz.0101.exr`.
pub fn output_path(
    input: &Path,
    out_dir: Option<&Path>,
    suffix: &str,
    format: FileFormat,
) -> PathBuf {
    let stem = input
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match stem.rsplit_once('.') {
        Some((base, frame))
            if !base.is_empty()
                && !frame.is_empty()
                && frame.bytes().all(|b| b.is_ascii_digit()) =>
        {
            format!("{base}{suffix}.{frame}.{}", format.extension())
        }
        _ => format!("{stem}{suffix}.{}", format.extension()),
    };
    match out_dir {
        Some(d) => d.join(name),
        None => input.with_file_name(name),
    }
}

/// One conversion of a batch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Planned {
    pub input: PathBuf,
    pub output: PathBuf,
}

/// A path with its directory resolved (symlinks, `.`/`..`), for comparing outputs that may not
/// exist yet.
fn resolved(p: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(p) {
        return c;
    }
    match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) => {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            std::fs::canonicalize(dir)
                .map(|d| d.join(name))
                .unwrap_or_else(|_| p.to_path_buf())
        }
        _ => p.to_path_buf(),
    }
}

/// Whether `a` and `b` are the same file (also through hard links), both existing.
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
        false
    }
    #[cfg(not(unix))]
    {
        match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

/// Pairs every input with its output (see [`output_path`]) and refuses a plan that could lose
/// data: an output that is an input (of this batch, by path or hard link), or two inputs
/// mapped to the same output.
pub fn plan(
    inputs: &[PathBuf],
    out_dir: Option<&Path>,
    suffix: &str,
    format: FileFormat,
) -> Result<Vec<Planned>, IoError> {
    let input_keys: HashMap<PathBuf, &PathBuf> = inputs.iter().map(|p| (resolved(p), p)).collect();
    let mut outputs: HashMap<PathBuf, &PathBuf> = HashMap::new();
    let mut planned = Vec::with_capacity(inputs.len());
    for input in inputs {
        let output = output_path(input, out_dir, suffix, format);
        let key = resolved(&output);
        if let Some(other) = input_keys.get(&key) {
            return Err(IoError::Invalid(format!(
                "{}: the output for {} would be written onto an input file; choose another --suffix or -o",
                output.display(),
                if *other == input { "itself".to_string() } else { input.display().to_string() }
            )));
        }
        if output.exists() {
            if let Some(i) = inputs.iter().find(|i| same_file(i, &output)) {
                return Err(IoError::Invalid(format!(
                    "{}: the output for {} is the input {} (a link to it); choose another --suffix or -o",
                    output.display(),
                    input.display(),
                    i.display()
                )));
            }
        }
        if let Some(prev) = outputs.insert(key, input) {
            return Err(IoError::Invalid(format!(
                "{} and {} would both be written to {}; convert them in separate runs or to separate -o directories",
                prev.display(),
                input.display(),
                output.display()
            )));
        }
        planned.push(Planned {
            input: input.clone(),
            output,
        });
    }
    Ok(planned)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_parse_and_partition() {
        assert_eq!(Shard::parse("2/3").unwrap(), Shard { index: 2, count: 3 });
        for bad in ["0/3", "4/3", "1/0", "x/2", "3", "1/y", ""] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        let items: Vec<usize> = (0..10).collect();
        let mut all: Vec<usize> = (1..=3)
            .flat_map(|k| Shard { index: k, count: 3 }.select(&items))
            .collect();
        all.sort();
        assert_eq!(all, items);
        assert_eq!(
            Shard { index: 1, count: 3 }.select(&items),
            vec![0, 3, 6, 9]
        );
    }

    #[test]
    fn output_names_keep_frame_numbers() {
        let f = FileFormat::Exr;
        assert_eq!(
            output_path(Path::new("a/plate.0101.exr"), None, "_xyz", f),
            Path::new("a/plate_xyz.0101.exr")
        );
        assert_eq!(
            output_path(
                Path::new("a/shot.tif"),
                Some(Path::new("out")),
                "_acescg",
                f
            ),
            Path::new("out/shot_acescg.exr")
        );
        assert_eq!(
            output_path(Path::new("v1.2.exr"), None, "_x", FileFormat::Tiff),
            Path::new("v1_x.2.tif")
        );
        assert_eq!(
            output_path(Path::new("take.final.exr"), None, "_x", f),
            Path::new("take.final_x.exr")
        );
    }

    #[test]
    fn plan_refuses_collisions() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.exr");
        let b = dir.path().join("a.tif");
        std::fs::write(&a, b"x").unwrap();
        std::fs::write(&b, b"x").unwrap();
        let e = plan(&[a.clone(), b], None, "_xyz", FileFormat::Exr).unwrap_err();
        assert!(e.to_string().contains("would both be written"), "{e}");
        let e = plan(std::slice::from_ref(&a), None, "", FileFormat::Exr).unwrap_err();
        assert!(e.to_string().contains("onto an input"), "{e}");
        let p = plan(std::slice::from_ref(&a), None, "_xyz", FileFormat::Exr).unwrap();
        assert_eq!(p[0].output, dir.path().join("a_xyz.exr"));
    }
}
