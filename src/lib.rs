//! # nsrm — camera colour correction on the GPU
//!
//! Maps a camera's linear raw RGB to CIE XYZ with one of four regression models — linear (LRM),
//! polynomial (PRM), root-polynomial (RPRM) and normalised-signal polynomial (NSRM, the paper
//! "Camera Color Correction Using Normalized Signal Polynomial Regression") — fitted on chart patches
//! on the CPU and applied per pixel by a WGSL compute shader through wgpu, or on the CPU.
//!
//! Data flows one way:
//!
//! ```text
//! spectra ─► spectral::simulate ─► TrainingSet ─► model::fit ─► Model ─► apply (cpu / gpu)
//! measured CSV ─────────────────────┘       └─► eval::evaluate (leave-one-out ΔE00)
//! ```
//!
//! ```
//! use nsrm::{model::{fit, Kind}, spectral::{simulate, Camera, Grid, Illuminant, Reflectances}};
//! let data = simulate(
//!     &Camera::from_name_or_path("nikon-d5100")?,
//!     &Illuminant::from_name_or_path("D65")?,
//!     &Reflectances::from_name_or_path("cc24")?,
//!     &Grid::default(),
//! )?;
//! let model = fit(Kind::Nsrm, 3, &data)?;
//! let xyz = model.apply_f64(data.rgb[0]);
//! assert!((xyz[1] - data.xyz[0][1]).abs() < 1.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Cargo features
//! The colour-science core (`spectral`, `colorimetry`, `model`, `eval`, `training`, `frame`) has
//! no optional dependency: `default-features = false` builds just that.
//!
//! | feature | brings |
//! |---|---|
//! | `gpu` | [`gpu`]: wgpu, the frame [`gpu::Engine`] and the embeddable [`gpu::Corrector`] |
//! | `io` | [`io`]: OpenEXR / TIFF frames and batches, PNG previews |
//! | `export` | `export`: LUTs and profiles other tools read (CLF, `.cube`, OCIO, DCTL, DCP); with `gpu` also `export::shader`, the baked shaders in WGSL, SPIR-V, GLSL, HLSL and MSL (naga's back ends) |
//! | `plot` | `eval::plot`: the paper's Fig. 1 as SVG or PNG |
//! | `chart` | chart detection in captured frames, synthetic chart frames and scenes; implies `io` |
//! | `farm` | [`farm`]: per-shard manifests, their verification, path mapping, farm job files; implies `io` |
//! | `cli` (default) | the `nsrm` binary; implies all of the above |
//!
//! A renderer embeds the correction pass with
//! `nsrm = { version = "0.1", default-features = false, features = ["gpu"] }`.
#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![cfg_attr(docsrs, feature(doc_auto_cfg))]

#[cfg(feature = "chart")]
pub mod chart;
/// The `nsrm` command line: argument parsing and one file per subcommand, over the library's
/// public API and its crate-private machinery (the output session, the batch plan, the farm
/// files). Not a library API: only [`cli::main`], the binary's entry point, is reachable.
#[cfg(feature = "cli")]
#[doc(hidden)]
pub mod cli;
pub mod colorimetry;
pub mod csv_table;
pub mod error;
pub mod eval;
#[cfg(feature = "export")]
pub mod export;
#[cfg(feature = "farm")]
pub mod farm;
pub mod frame;
#[cfg(feature = "gpu")]
pub mod gpu;
#[cfg(feature = "io")]
pub mod io;
pub mod limits;
pub mod model;
pub mod output;
pub mod spectral;
pub mod training;
mod training_set;

pub use frame::{Frame, Layout};
pub use model::{Kind, Model};
pub use training::TrainingSet;
