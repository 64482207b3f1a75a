//! Applying models on the GPU with wgpu: adapter and device setup ([`GpuContext`]), the
//! [`Corrector`] (one model's pipeline and uniform, recording into a caller's encoder), the
//! frame [`Engine`] built on it (tiling, double-buffered upload / compute / read-back), shader
//! generation (`shader`; the self-contained shaders other programs load are written by
//! `nsrm_export::shader`).
//!
//! The shaders follow the pixel policy of `model::pixel` (the README's *Pixel policy*) exactly: NaN / Inf propagate, NSRM
//! with `s = R+G+B ≤ 0` gives 0, negative channels are allowed (RPRM's roots keep the sign),
//! nothing is clamped. They compute in f32; against the f64 reference the relative error per
//! value stays within 1e-5 (see `gpu_tests.rs`).
//!
//! # Adapter selection
//! * Backends: `WGPU_BACKEND` (e.g. `vulkan`, `gl`, `metal`, `dx12`) if set, else the primary
//!   backends (Vulkan, Metal, DX12; not GL, where Mesa shows llvmpipe a second time).
//! * Adapter: the default one (`WGPU_POWER_PREF=low|high` is honoured), unless
//!   [`GpuOptions::adapter`] or else the `NSRM_ADAPTER` environment variable names a
//!   substring of the wanted adapter's name (case-insensitive, e.g. `llvmpipe`, `nvidia`).
//! * The device gets the adapter's own limits and, where offered, timestamp queries.
//!
//! ```no_run
//! use nsrm::gpu::{open, DeviceChoice, GpuOptions};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let model: nsrm::Model = unimplemented!();
//! # let mut frame: nsrm::Frame = unimplemented!();
//! match open(DeviceChoice::Auto, &GpuOptions::default())? {
//!     Some(mut engine) => engine.apply(&model, &mut frame)?,
//!     None => model.apply_frame(&mut frame), // no adapter: the CPU frame path
//! }
//! # Ok(()) }
//! ```

mod context;
mod corrector;
mod engine;
// The engine's and the program's tests share `gpu_tests`' adapter and frames, which need `io`.
#[cfg(test)]
mod engine_tests;
#[cfg(test)]
mod gpu_tests;
#[cfg(test)]
mod program_tests;
pub(crate) mod shader;
mod shader_check;

/// The WGSL printer's baked shaders and the validation every shader here is held to (what
/// `nsrm-export` translates to SPIR-V, GLSL, HLSL and MSL).
pub use self::shader::{
    baked_wgsl, validate as validate_wgsl, validate_module as validate_naga_module, ENTRY_POINT,
};
pub use self::{
    context::GpuContext, corrector::Corrector, engine::Engine, engine::GpuTiming, shader::Target,
    shader::TexelFormat, shader_check::ShaderCheck,
};
/// The naga this crate validates its WGSL with (the modules [`validate_wgsl`] returns).
pub use naga;
/// The wgpu this crate is built against: a renderer embedding a [`Corrector`] records into
/// this version's encoders and textures.
pub use wgpu;

/// The driver hint every "no adapter" error carries.
pub(crate) const NO_ADAPTER_HINT: &str =
    "no GPU adapter found: install a Vulkan driver (e.g. apt-get install mesa-vulkan-drivers libvulkan1)";

/// Errors of the GPU path.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter on the enabled backends.
    #[error("{NO_ADAPTER_HINT} ({detail})")]
    NoAdapter {
        /// The backends tried, or wgpu's reason.
        detail: String,
    },
    /// Adapters exist, but none matches the requested name.
    #[error("no GPU adapter matches `{wanted}`; available: {}", available.join("; "))]
    AdapterNotFound {
        /// The adapter name asked for.
        wanted: String,
        /// The names of the adapters present.
        available: Vec<String>,
    },
    /// Only a software rasteriser (device type `Cpu`, e.g. Mesa's lavapipe) is there, and the
    /// caller asked for hardware (the `Auto` policy).
    #[error("only a software adapter is present ({adapter}); the CPU path is faster than it")]
    SoftwareOnly {
        /// The software adapter's name.
        adapter: String,
    },
    /// The adapter refused to open a device.
    #[error("cannot open the GPU device: {0}")]
    RequestDevice(#[from] wgpu::RequestDeviceError),
    /// naga rejected a shader (a bug in the generated source, or an unsupported target).
    #[error("shader error ({stage}): {message}")]
    Shader {
        /// The step that failed (WGSL parse or validation).
        stage: &'static str,
        /// naga's diagnostic.
        message: String,
    },
    /// A shader could not be translated to another language.
    #[error("cannot translate the shader to {lang}: {message}")]
    Export {
        /// The target shading language.
        lang: String,
        /// Why the translation failed.
        message: String,
    },
    /// `set_model` with a model of another kind or order than the corrector was built for.
    #[error("this corrector is for {expected}; {got} needs a new one")]
    ModelMismatch {
        /// The model kind and order the corrector was built for.
        expected: String,
        /// The kind and order of the model given.
        got: String,
    },
    /// Buffers, textures or sizes that the corrector cannot take.
    #[error("{0}")]
    Usage(String),
    /// wgpu reported a validation or out-of-memory error.
    #[error("wgpu error: {0}")]
    Wgpu(String),
    /// Mapping a buffer for read-back failed.
    #[error("GPU read-back failed: {0}")]
    Map(#[from] wgpu::BufferAsyncError),
    /// Reading a range of a mapped buffer failed.
    #[error("GPU read-back failed: {0}")]
    MapRange(#[from] wgpu::MapRangeError),
    /// Waiting for submitted GPU work failed.
    #[error("waiting for the GPU failed: {0}")]
    Poll(#[from] wgpu::PollError),
}

impl GpuError {
    /// True for buffers, textures or models the caller passed that a corrector cannot take.
    pub fn is_usage(&self) -> bool {
        matches!(self, GpuError::Usage(_) | GpuError::ModelMismatch { .. })
    }
}

/// Options for [`Engine::new`] / [`open`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// A substring of the adapter's name (case-insensitive); `None`: the `NSRM_ADAPTER`
    /// environment variable, else the default adapter.
    pub adapter: Option<String>,
    /// Pixels per tile streamed through the GPU; `None`: 1 Mpixel (capped so one tile fits in
    /// a storage binding). Small values are for tests.
    pub tile_pixels: Option<usize>,
}

/// Where to apply a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DeviceChoice {
    /// A hardware GPU if there is one, else the CPU: a software rasteriser (such as Mesa's
    /// lavapipe) is slower than the CPU path, so it is used only when named (an adapter name,
    /// or `NSRM_ADAPTER`).
    #[cfg_attr(feature = "clap", value(name = "auto"))]
    Auto,
    /// The GPU (any adapter, software ones included), or an error.
    #[cfg_attr(feature = "clap", value(name = "gpu"))]
    Gpu,
    /// The CPU.
    #[cfg_attr(feature = "clap", value(name = "cpu"))]
    Cpu,
}

impl DeviceChoice {
    /// Parses `auto`, `gpu` or `cpu` (case-insensitive; the unit tests hold the command line's
    /// `--device` values to it).
    pub fn parse(s: &str) -> Option<DeviceChoice> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Some(DeviceChoice::Auto),
            "gpu" => Some(DeviceChoice::Gpu),
            "cpu" => Some(DeviceChoice::Cpu),
            _ => None,
        }
    }

    /// `auto`, `gpu` or `cpu`.
    pub fn name(self) -> &'static str {
        match self {
            DeviceChoice::Auto => "auto",
            DeviceChoice::Gpu => "gpu",
            DeviceChoice::Cpu => "cpu",
        }
    }
}

/// Why [`open_device`] chose the CPU path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CpuReason {
    /// The caller asked for the CPU.
    Asked,
    /// `Auto` found no adapter.
    NoAdapter {
        /// What wgpu said.
        detail: String,
    },
    /// `Auto` found only a software rasteriser (the CPU path is faster).
    SoftwareOnly {
        /// The software adapter's name.
        adapter: String,
    },
}

impl std::fmt::Display for CpuReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CpuReason::Asked => write!(f, "the CPU was asked for"),
            // wgpu's reason is kept: where a driver is installed and the adapter was not found
            // (once, under load), it is what says why.
            CpuReason::NoAdapter { detail } => write!(
                f,
                "no GPU adapter found ({detail}; for the GPU install a Vulkan driver, e.g. mesa-vulkan-drivers libvulkan1)"
            ),
            CpuReason::SoftwareOnly { adapter } => write!(
                f,
                "the only GPU adapter, {adapter}, is a software rasteriser, slower than the CPU path"
            ),
        }
    }
}

/// What [`open_device`] opened: a GPU engine, or the CPU path and why.
#[derive(Debug)]
pub enum Opened {
    /// A GPU engine on the adapter found.
    Gpu(Box<Engine>),
    /// The CPU path, and why.
    Cpu(CpuReason),
}

/// Opens the engine the choice asks for, saying why when it is the CPU.
///
/// * `Auto`: a hardware adapter's engine; a software one only when named by
///   [`GpuOptions::adapter`] or `NSRM_ADAPTER`; else the CPU with the reason. Other failures
///   (a named adapter that does not exist, a device that cannot be opened) are errors.
/// * `Gpu`: the engine on any adapter (software included), or an error.
/// * `Cpu`: the CPU.
pub fn open_device(choice: DeviceChoice, opts: &GpuOptions) -> Result<Opened, GpuError> {
    let gpu = |e: Engine| Opened::Gpu(Box::new(e));
    match choice {
        DeviceChoice::Cpu => Ok(Opened::Cpu(CpuReason::Asked)),
        DeviceChoice::Gpu => Engine::new(opts).map(gpu),
        DeviceChoice::Auto => match Engine::new_hardware(opts) {
            Ok(e) => Ok(gpu(e)),
            Err(GpuError::NoAdapter { detail }) => Ok(Opened::Cpu(CpuReason::NoAdapter { detail })),
            Err(GpuError::SoftwareOnly { adapter }) => {
                Ok(Opened::Cpu(CpuReason::SoftwareOnly { adapter }))
            }
            Err(e) => Err(e),
        },
    }
}

/// Opens the engine the choice asks for (`open_device` without the reason).
///
/// * `Auto`: `Ok(Some(engine))` on a hardware adapter (or a software one that is named),
///   `Ok(None)` otherwise; other failures (an adapter name that matches nothing, a device that
///   cannot be opened) are errors.
/// * `Gpu`: the engine, or an error ([`GpuError::NoAdapter`] names the driver to install).
/// * `Cpu`: `Ok(None)`.
///
/// ```
/// use nsrm::gpu::{open, DeviceChoice, GpuOptions};
/// assert!(open(DeviceChoice::Cpu, &GpuOptions::default()).unwrap().is_none());
/// ```
pub fn open(choice: DeviceChoice, opts: &GpuOptions) -> Result<Option<Engine>, GpuError> {
    Ok(match open_device(choice, opts)? {
        Opened::Gpu(e) => Some(*e),
        Opened::Cpu(_) => None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cpu_fallback_says_wgpus_reason() {
        let r = CpuReason::NoAdapter {
            detail: "No suitable graphics adapter found; Vulkan: ERROR_INITIALIZATION_FAILED"
                .into(),
        };
        assert!(r.to_string().contains("ERROR_INITIALIZATION_FAILED"), "{r}");
    }

    #[test]
    fn device_choice_parses() {
        for c in [DeviceChoice::Auto, DeviceChoice::Gpu, DeviceChoice::Cpu] {
            assert_eq!(DeviceChoice::parse(c.name()), Some(c));
        }
        assert_eq!(DeviceChoice::parse(" Auto "), Some(DeviceChoice::Auto));
        assert_eq!(DeviceChoice::parse("GPU"), Some(DeviceChoice::Gpu));
        assert_eq!(DeviceChoice::parse("tpu"), None);
        assert_eq!(DeviceChoice::parse(""), None);
    }

    #[test]
    fn adapter_errors_name_the_driver_or_the_adapters_there_are() {
        // A real selection that cannot succeed: with adapters present it must list them, without
        // any it must say which driver to install and which backends it looked at.
        let opts = GpuOptions {
            adapter: Some("no-such-adapter-5f3a".into()),
            tile_pixels: None,
        };
        match GpuContext::new(&opts) {
            Err(e @ GpuError::AdapterNotFound { .. }) => {
                let GpuError::AdapterNotFound { wanted, available } = &e else {
                    unreachable!()
                };
                assert_eq!(wanted, "no-such-adapter-5f3a");
                assert!(!available.is_empty());
                let msg = e.to_string();
                assert!(msg.contains("`no-such-adapter-5f3a`"), "{msg}");
                assert!(available.iter().all(|a| msg.contains(a.as_str())), "{msg}");
            }
            Err(e @ GpuError::NoAdapter { .. }) => {
                let msg = e.to_string();
                assert!(msg.contains("mesa-vulkan-drivers"), "{msg}");
                assert!(msg.contains("backends"), "{msg}");
            }
            Err(e) => panic!("unexpected error: {e}"),
            Ok(_) => panic!("an adapter named no-such-adapter-5f3a was found"),
        }
        // `--device cpu` never opens one.
        assert!(open(DeviceChoice::Cpu, &GpuOptions::default())
            .unwrap()
            .is_none());
    }
}
