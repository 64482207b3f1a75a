//! Which of the library's errors are the caller's usage mistake, and which parameter an error is
//! about, asked of any link of an `anyhow` chain: the one place that knows every room's error
//! type (each type classifies itself with its own `is_usage` / `concern` methods).

use crate::error::Concern;

/// True when `err` is one of this crate's errors and a usage error (see each type's
/// `is_usage`).
pub(crate) fn is_usage(err: &(dyn std::error::Error + 'static)) -> bool {
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
        crate::spectral::SpectralError,
        crate::training::TrainingError,
        crate::model::ModelError,
        crate::output::WriteError,
        crate::io::IoError,
        crate::io::batch::PlanError,
        crate::farm::FarmError,
        crate::export::ExportError,
        crate::chart::ChartError,
        crate::chart::capture::CaptureError,
        crate::eval::plot::PlotError,
        crate::gpu::GpuError,
    );
    false
}

/// The parameter `err` is about, when it is one of this crate's errors that is about one (see
/// the `concern` method of `ModelError`, `IoError` and `ChartError`).
pub(crate) fn concern(err: &(dyn std::error::Error + 'static)) -> Option<Concern> {
    if let Some(e) = err.downcast_ref::<crate::model::ModelError>() {
        return e.concern();
    }
    if let Some(e) = err.downcast_ref::<crate::io::IoError>() {
        return e.concern();
    }
    if let Some(e) = err.downcast_ref::<crate::chart::ChartError>() {
        return e.concern();
    }
    if let Some(e) = err.downcast_ref::<crate::chart::capture::CaptureError>() {
        return e.concern();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Param;

    #[test]
    fn concerns_name_the_parameter() {
        let m = crate::model::ModelError::NoWhite;
        assert_eq!(concern(&m), Some(Concern::Remedy(Param::WhitePatch)));
        assert_eq!(concern(&crate::model::ModelError::Degenerate), None);
        {
            let e = crate::chart::synthetic::check_exposure_noise(f64::INFINITY, 0.0).unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Exposure)));
            assert!(is_usage(&e), "{e}");
            let e = crate::chart::synthetic::check_exposure_noise(1.0, -1.0).unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Noise)));
        }
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
        let data = crate::model::ModelError::Degenerate;
        assert!(!is_usage(&data));
        let unknown = crate::spectral::Camera::from_name_or_path("no-such-camera").unwrap_err();
        assert!(!is_usage(&unknown), "{unknown}");
        // Not one of the crate's errors.
        assert!(!is_usage(&std::io::Error::other("x")));
        {
            let shard = crate::io::batch::Shard::parse("0/3").unwrap_err();
            assert!(is_usage(&shard), "{shard}");
            let suffix = crate::io::batch::validate_suffix("a/b").unwrap_err();
            assert!(is_usage(&suffix), "{suffix}");
        }
    }
}
