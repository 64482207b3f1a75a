//! The f32 guard's second measurement: a fitted model evaluated by the GPU shader `apply` uses,
//! on a hardware adapter (or the one `NSRM_ADAPTER` names), beside the fast CPU kernel.

use super::{Engine, GpuError, GpuOptions};
use crate::frame::{Frame, Layout};
use crate::model::fit::F32Evaluator;
use crate::Model;
use std::sync::Mutex;

/// The GPU shader as an [`F32Evaluator`] for [`crate::FitOptions::f32_also`]: `fit` measures
/// the f32 error of its model here too where a GPU is open, and the guard decides on the larger.
#[derive(Debug)]
pub struct ShaderCheck {
    engine: Mutex<Engine>,
    name: String,
}

impl ShaderCheck {
    /// Opens the GPU as `apply --device auto` would: a hardware adapter, or a software one
    /// (lavapipe) only when `opts` or `NSRM_ADAPTER` names it ([`GpuError::SoftwareOnly`]
    /// otherwise).
    pub fn open(opts: &GpuOptions) -> Result<ShaderCheck, GpuError> {
        let engine = Engine::new_hardware(opts)?;
        let name = format!("GPU {}", engine.adapter_name());
        Ok(ShaderCheck {
            engine: Mutex::new(engine),
            name,
        })
    }
}

impl F32Evaluator for ShaderCheck {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn evaluate(&self, model: &Model, rgb: &[f32]) -> Option<Vec<f32>> {
        let mut frame = Frame::from_data(rgb.len() / 3, 1, Layout::Rgb, rgb.to_vec())?;
        let mut engine = self.engine.lock().ok()?;
        engine.apply(model, &mut frame).ok()?;
        Some(frame.data)
    }
}
