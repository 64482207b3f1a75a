//! Which library errors are the caller's usage mistake (a malformed or contradictory request:
//! a bad grid or patch spec, an unknown kind, chart or shard, outputs that would collide, a LUT
//! size out of range) rather than a failure of the data, the files or the device. A command-line
//! front end maps the first kind to its usage exit status and adds its own flag names; nothing
//! here knows about flags.
//!
//! Each error type has an `is_usage` method; [`is_usage`] asks any error (for example each link
//! of an `anyhow` chain) whether it is one of this crate's usage errors.
//!
//! An error that is about one parameter of the request says which, as a typed [`Concern`]: the
//! value given for a [`Param`] is wrong, or giving that parameter is the way out (a chart that
//! was not found can be read from its corners). Messages name parameters in words ("the
//! exposure", "the corners"); a front end turns the concern into its own spelling ([`concern`]
//! asks any error, as [`is_usage`] does).

use crate::model::ModelError;
use crate::output::WriteError;
use crate::spectral::SpectralError;
use crate::training::TrainingError;

/// A parameter of a request that an error can be about, named for what it is (the option
/// structs' fields), not for any front end's spelling of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Param {
    /// The most pixels a frame may have (`io::Limits::max_pixels`).
    MaxPixels,
    /// The EXR layer holding the camera RGB (`io::ReadOptions::layer`).
    Layer,
    /// A rendered chart's exposure (`io::chart::ChartOptions::exposure`).
    Exposure,
    /// A rendered chart's noise (`io::chart::ChartOptions::noise`).
    Noise,
    /// A rendered chart's patch size (`io::chart::ChartOptions::patch_size`).
    PatchSize,
    /// A rendered chart's gap between patches (`io::chart::ChartOptions::gap`).
    Gap,
    /// A rendered chart's columns (`io::chart::ChartOptions::columns`).
    Columns,
    /// The four corners of a photographed chart (`chart::parse_corners`).
    Corners,
    /// The flat-field frame of a chart capture (`chart::flat`).
    Flat,
    /// The reference white of Lab reference values (`chart::Reference::parse`).
    ReferenceWhite,
    /// The reflectance spectra of a chart (`chart::scene::ChartColours::simulate`).
    Reflectances,
    /// A capture's white (clipping) level (`chart::ExtractOptions::white_level`).
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

impl SpectralError {
    /// True for a malformed wavelength grid.
    pub fn is_usage(&self) -> bool {
        matches!(self, SpectralError::Grid { .. })
    }
}

impl TrainingError {
    /// True for a malformed patch selection or white point, a white that is missing or that
    /// contradicts the file's.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            TrainingError::PatchSpec { .. }
                | TrainingError::White { .. }
                | TrainingError::NeedsWhite { .. }
                | TrainingError::WhiteConflict { .. }
        )
    }
}

impl ModelError {
    /// True for an unknown model kind, an order outside 1..=4 and a malformed fit option.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            ModelError::UnknownKind(_) | ModelError::Order(_) | ModelError::Spec(_)
        )
    }

    /// A fit that needs the camera response of a white the data lacks: naming a neutral patch
    /// ([`Param::WhitePatch`]) is the way out.
    pub fn concern(&self) -> Option<Concern> {
        match self {
            ModelError::NoWhite => Some(Concern::Remedy(Param::WhitePatch)),
            _ => None,
        }
    }
}

#[cfg(feature = "io")]
impl crate::io::IoError {
    /// True for inputs that name no frame, a malformed shard, and a parameter value out of range.
    pub fn is_usage(&self) -> bool {
        use crate::io::IoError;
        matches!(
            self,
            IoError::NoMatch { .. }
                | IoError::Shard { .. }
                | IoError::Write(
                    WriteError::OutputIsInput { .. }
                        | WriteError::SameOutput { .. }
                        | WriteError::NoFileName(_)
                )
                | IoError::Param {
                    concern: Concern::Value(_),
                    ..
                }
        )
    }

    /// The parameter this error is about: a frame over the pixel limit, a layer that is not
    /// there or not named where several are, a rendered chart's option out of range.
    pub fn concern(&self) -> Option<Concern> {
        use crate::io::IoError;
        match self {
            IoError::OverLimit { .. } => Some(Concern::Remedy(Param::MaxPixels)),
            IoError::Channels { concern, .. } => *concern,
            IoError::Param { concern, .. } => Some(*concern),
            _ => None,
        }
    }
}

#[cfg(feature = "io")]
impl crate::io::batch::PlanError {
    /// True for a batch that cannot be planned as asked (collisions, existing outputs, a bad
    /// suffix); false for a directory that cannot be set up.
    pub fn is_usage(&self) -> bool {
        matches!(self, crate::io::batch::PlanError::Usage(_))
    }
}

#[cfg(feature = "export")]
impl crate::export::ExportError {
    /// True for export options out of range.
    pub fn is_usage(&self) -> bool {
        match self {
            crate::export::ExportError::Usage(_) => true,
            crate::export::ExportError::Write(w) => w.is_usage(),
            _ => false,
        }
    }
}

#[cfg(feature = "chart")]
impl crate::chart::ChartError {
    /// True for an unknown chart name, scene options out of range, and a parameter value that is
    /// malformed or does not fit the frame (corners, white level, flat frame).
    pub fn is_usage(&self) -> bool {
        use crate::chart::ChartError;
        matches!(
            self,
            ChartError::UnknownChart(_)
                | ChartError::Options(_)
                | ChartError::Param {
                    concern: Concern::Value(_),
                    ..
                }
        )
    }

    /// The parameter this error is about; a chart that was not found can always be read from
    /// its corners ([`Param::Corners`]).
    pub fn concern(&self) -> Option<Concern> {
        use crate::chart::ChartError;
        match self {
            ChartError::Param { concern, .. } => Some(*concern),
            ChartError::NotFound(_) => Some(Concern::Remedy(Param::Corners)),
            ChartError::Io(e) => e.concern(),
            _ => None,
        }
    }
}

#[cfg(feature = "plot")]
impl crate::eval::plot::PlotError {
    /// True for a plot file name that is neither `.png` nor `.svg`.
    pub fn is_usage(&self) -> bool {
        matches!(self, crate::eval::plot::PlotError::Format(_))
    }
}

#[cfg(feature = "gpu")]
impl crate::gpu::GpuError {
    /// True for buffers, textures or models the caller passed that a corrector cannot take.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            crate::gpu::GpuError::Usage(_) | crate::gpu::GpuError::ModelMismatch { .. }
        )
    }
}

/// True when `err` is one of this crate's errors and a usage error (see each type's
/// `is_usage`).
pub fn is_usage(err: &(dyn std::error::Error + 'static)) -> bool {
    macro_rules! check {
        ($($(#[$cfg:meta])* $ty:ty),+ $(,)?) => {
            $(
                $(#[$cfg])*
                if let Some(e) = err.downcast_ref::<$ty>() {
                    return e.is_usage();
                }
            )+
        };
    }
    check!(
        SpectralError,
        TrainingError,
        ModelError,
        WriteError,
        #[cfg(feature = "io")]
        crate::io::IoError,
        #[cfg(feature = "io")]
        crate::io::batch::PlanError,
        #[cfg(feature = "farm")]
        crate::farm::FarmError,
        #[cfg(feature = "export")]
        crate::export::ExportError,
        #[cfg(feature = "chart")]
        crate::chart::ChartError,
        #[cfg(feature = "chart")]
        crate::chart::capture::CaptureError,
        #[cfg(feature = "plot")]
        crate::eval::plot::PlotError,
        #[cfg(feature = "gpu")]
        crate::gpu::GpuError,
    );
    false
}

/// The parameter `err` is about, when it is one of this crate's errors that is about one (see
/// the `concern` method of [`ModelError`], `io::IoError` and `chart::ChartError`).
pub fn concern(err: &(dyn std::error::Error + 'static)) -> Option<Concern> {
    if let Some(e) = err.downcast_ref::<ModelError>() {
        return e.concern();
    }
    #[cfg(feature = "io")]
    if let Some(e) = err.downcast_ref::<crate::io::IoError>() {
        return e.concern();
    }
    #[cfg(feature = "chart")]
    if let Some(e) = err.downcast_ref::<crate::chart::ChartError>() {
        return e.concern();
    }
    #[cfg(feature = "chart")]
    if let Some(e) = err.downcast_ref::<crate::chart::capture::CaptureError>() {
        return e.concern();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

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
            for (i, line) in std::fs::read_to_string(f).unwrap().lines().enumerate() {
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

    #[test]
    fn concerns_name_the_parameter() {
        let m = ModelError::NoWhite;
        assert_eq!(concern(&m), Some(Concern::Remedy(Param::WhitePatch)));
        assert_eq!(concern(&ModelError::Degenerate), None);
        #[cfg(feature = "io")]
        {
            let e = crate::io::chart::check_exposure_noise(f64::INFINITY, 0.0).unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Exposure)));
            assert!(is_usage(&e), "{e}");
            let e = crate::io::chart::check_exposure_noise(1.0, -1.0).unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Noise)));
        }
        #[cfg(feature = "chart")]
        {
            let e = crate::chart::parse_corners("1,2 3,4").unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Corners)));
            assert!(is_usage(&e), "{e}");
        }
    }

    #[test]
    fn usage_errors_are_told_apart_from_data_errors() {
        let grid = crate::spectral::Grid::parse("400:700").unwrap_err();
        assert!(grid.is_usage() && is_usage(&grid), "{grid}");
        let kind = crate::model::Kind::parse("xyz").unwrap_err();
        assert!(is_usage(&kind), "{kind}");
        let data = ModelError::Degenerate;
        assert!(!is_usage(&data));
        let unknown = crate::spectral::Camera::from_name_or_path("no-such-camera").unwrap_err();
        assert!(!is_usage(&unknown), "{unknown}");
        // Not one of the crate's errors.
        assert!(!is_usage(&std::io::Error::other("x")));
        #[cfg(feature = "io")]
        {
            let shard = crate::io::batch::Shard::parse("0/3").unwrap_err();
            assert!(is_usage(&shard), "{shard}");
            let suffix = crate::io::batch::validate_suffix("a/b").unwrap_err();
            assert!(is_usage(&suffix), "{suffix}");
        }
    }
}
