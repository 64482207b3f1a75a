//! Which of the library's errors are the caller's usage mistake, and which parameter an error is
//! about, asked of any link of an `anyhow` chain: the one place that knows every room's error
//! type (each type classifies itself with its own `is_usage` / `concern` methods).

use nsrm_io::Concern;

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
        nsrm::SpectralError,
        nsrm::TrainingError,
        nsrm::ModelError,
        nsrm_output::WriteError,
        nsrm_io::IoError,
        nsrm_io::batch::PlanError,
        crate::farmlib::FarmError,
        nsrm_export::ExportError,
        nsrm_chart::ChartError,
        nsrm_chart::capture::CaptureError,
        nsrm::plot::PlotError,
        nsrm::gpu::GpuError,
    );
    false
}

/// The parameter `err` is about, when it is one of this crate's errors that is about one (see
/// the `concern` method of `ModelError`, `IoError` and `ChartError`).
pub(crate) fn concern(err: &(dyn std::error::Error + 'static)) -> Option<Concern> {
    if let Some(e) = err.downcast_ref::<nsrm::ModelError>() {
        return e.concern();
    }
    if let Some(e) = err.downcast_ref::<nsrm_io::IoError>() {
        return e.concern();
    }
    if let Some(e) = err.downcast_ref::<nsrm_chart::ChartError>() {
        return e.concern();
    }
    if let Some(e) = err.downcast_ref::<nsrm_chart::capture::CaptureError>() {
        return e.concern();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use nsrm_io::Param;

    #[test]
    fn concerns_name_the_parameter() {
        let m = nsrm::ModelError::NoWhite;
        assert_eq!(concern(&m), Some(Concern::Remedy(Param::WhitePatch)));
        assert_eq!(concern(&nsrm::ModelError::Degenerate), None);
        {
            let e = nsrm_chart::synthetic::check_exposure_noise(f64::INFINITY, 0.0).unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Exposure)));
            assert!(is_usage(&e), "{e}");
            let e = nsrm_chart::synthetic::check_exposure_noise(1.0, -1.0).unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Noise)));
        }
        {
            let e = nsrm_chart::parse_corners("1,2 3,4").unwrap_err();
            assert_eq!(concern(&e), Some(Concern::Value(Param::Corners)));
            assert!(is_usage(&e), "{e}");
        }
    }

    #[test]
    fn usage_errors_are_told_apart_from_data_errors() {
        let grid = nsrm::Grid::parse("400:700").unwrap_err();
        assert!(grid.is_usage() && is_usage(&grid), "{grid}");
        let kind = nsrm::Kind::parse("xyz").unwrap_err();
        assert!(is_usage(&kind), "{kind}");
        let data = nsrm::ModelError::Degenerate;
        assert!(!is_usage(&data));
        let unknown = nsrm::Camera::from_name_or_path("no-such-camera").unwrap_err();
        assert!(!is_usage(&unknown), "{unknown}");
        // Not one of the crate's errors.
        assert!(!is_usage(&std::io::Error::other("x")));
        {
            let shard = nsrm_io::batch::Shard::parse("0/3").unwrap_err();
            assert!(is_usage(&shard), "{shard}");
            let suffix = nsrm_io::batch::validate_suffix("a/b").unwrap_err();
            assert!(is_usage(&suffix), "{suffix}");
        }
    }
}
