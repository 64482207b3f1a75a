//! Which library errors are the caller's usage mistake (a malformed or contradictory request:
//! a bad grid or patch spec, an unknown kind, chart or shard, outputs that would collide, a LUT
//! size out of range) rather than a failure of the data, the files or the device. A command-line
//! front end maps the first kind to its usage exit status and adds its own flag names; nothing
//! here knows about flags.
//!
//! Each error type has an `is_usage` method; [`is_usage`] asks any error (for example each link
//! of an `anyhow` chain) whether it is one of this crate's usage errors.

use crate::model::ModelError;
use crate::spectral::SpectralError;
use crate::training::TrainingError;

impl SpectralError {
    /// True for a malformed wavelength grid.
    pub fn is_usage(&self) -> bool {
        matches!(self, SpectralError::Grid { .. })
    }
}

impl TrainingError {
    /// True for a malformed patch selection or white point.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            TrainingError::PatchSpec { .. } | TrainingError::White { .. }
        )
    }
}

impl ModelError {
    /// True for an unknown model kind or an order outside 1..=4.
    pub fn is_usage(&self) -> bool {
        matches!(self, ModelError::UnknownKind(_) | ModelError::Order(_))
    }
}

#[cfg(feature = "io")]
impl crate::io::IoError {
    /// True for inputs that name no frame and for a malformed shard.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            crate::io::IoError::NoMatch { .. } | crate::io::IoError::Shard { .. }
        )
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
        matches!(self, crate::export::ExportError::Usage(_))
    }
}

#[cfg(feature = "chart")]
impl crate::chart::ChartError {
    /// True for an unknown chart name.
    pub fn is_usage(&self) -> bool {
        matches!(self, crate::chart::ChartError::UnknownChart(_))
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
        #[cfg(feature = "io")]
        crate::io::IoError,
        #[cfg(feature = "io")]
        crate::io::batch::PlanError,
        #[cfg(feature = "export")]
        crate::export::ExportError,
        #[cfg(feature = "chart")]
        crate::chart::ChartError,
        #[cfg(feature = "plot")]
        crate::eval::plot::PlotError,
        #[cfg(feature = "gpu")]
        crate::gpu::GpuError,
    );
    false
}

#[cfg(test)]
mod tests {
    use super::*;

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
