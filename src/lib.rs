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
//! spectra ─► simulate ─► TrainingSet ─► fit ─► Model ─► apply (CPU pixel / CPU frame / GPU)
//! measured CSV ───────────┘      └─► evaluate (leave-one-out ΔE00)
//! ```
//!
//! ```
//! use nsrm::{fit, simulate_named, Grid, Kind};
//! // Built-in names, or paths of CSV files with the same columns.
//! let data = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default())?;
//! let model = fit(Kind::Nsrm, 3, &data)?;
//! let xyz = model.apply_f64(data.rgb[0]);
//! assert!((xyz[1] - data.xyz[0][1]).abs() < 1.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # The API
//! The colour-science core is one flat list of items at the crate root (below, grouped as the
//! documentation lists them): frames, models (fit, file, apply), the CPU frame kernels,
//! dual-illuminant profiles, colorimetry, spectral simulation, training sets and evaluation;
//! beside it the pixel program ([`pixel`]), the capped readers ([`limits`]) and the CSV reader
//! ([`csv_table`]) the other crates of the workspace build on. The rooms behind optional features
//! are modules: [`gpu`], `plot`. Frames in and out, chart reading and the exports are crates of
//! their own over this one (`nsrm-io`, `nsrm-chart`, `nsrm-export`), and the `nsrm` command
//! line is the `nsrm-cli` package (`crates/nsrm-cli`), built on their public APIs only.
//!
//! # Applying a model: one way per back end
//! | back end | the way | notes |
//! |---|---|---|
//! | CPU, one pixel | [`Model::apply_f64`] | f64, the reference every other path is checked against |
//! | CPU, a frame | [`Model::apply_frame`] | f32, vectorised, on every thread of rayon's current pool (`ThreadPool::install` to choose the threads) |
//! | GPU, a frame | `gpu::Engine::apply` | owns its device; tiles the frame through upload, compute and read-back |
//! | GPU, inside a renderer | `gpu::Corrector` | records the correction into the caller's encoder, on the caller's buffers or textures |
//!
//! All four follow one pixel policy (NaN and ±Inf propagate, NSRM with `R+G+B ≤ 0` gives 0,
//! negative channels allowed, nothing clamped) and agree with [`Model::apply_f64`] to f32
//! precision ([`F32_TOLERANCE_DE00`] on the training patches).
//!
//! # Cargo features
//! The colour-science core has no optional dependency: `default-features = false` builds just
//! that.
//!
//! | feature | brings |
//! |---|---|
//! | `gpu` (default) | `gpu`: wgpu, the frame `gpu::Engine` and the embeddable `gpu::Corrector`, the WGSL printer |
//! | `plot` | `plot`: the paper's Fig. 1 as SVG or PNG |
//! | `clap` | clap's `ValueEnum` on the library's enums (the command line's flag values) |
//! | `full` | `gpu` and `plot`: what the `nsrm` binary uses |
//!
//! A renderer embeds the correction pass with
//! `nsrm = { version = "0.1", default-features = false, features = ["gpu"] }`.
#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![warn(missing_docs)]
#![cfg_attr(docsrs, feature(doc_auto_cfg))]

mod colorimetry;
pub mod csv_table;
mod error;
mod eval;
mod frame;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod limits;
mod model;
mod spectral;
mod training;
mod training_set;

/// The unit tests' kit, shared with the integration tests (public API only; `nsrm` names this
/// crate in it).
#[cfg(test)]
extern crate self as nsrm;
#[cfg(test)]
#[path = "../tests/all/common/kit.rs"]
#[allow(unreachable_pub, dead_code)]
mod kit;

// The colour-science core (the names grouped as the documentation lists them).
// What an error is about: the parameter at fault and how (`nsrm-io`'s and `nsrm-chart`'s
// errors classify themselves with these).
pub use error::{Concern, Param};

// Frames: the pixels every apply path takes.
pub use frame::{Frame, Layout};

// Models: kinds, fitting, the model file, applying on the CPU, the output space folded in.
pub use model::fit::{fit_with, F32GuardChange, Fit, FitOptions, FitReport, F32_TOLERANCE_DE00};
pub use model::fit::{F32Evaluator, Normalise, Objective, Ridge, White as FitWhite};
pub use model::output::output_model;
pub use model::terms::MAX_ORDER;
pub use model::{fit, Kind, Model, ModelError};

/// The pixel program: what every apply path does with a pixel (a kind's [`Step`](pixel::Step)s
/// over its [`Term`](pixel::Term) list), the one description the fast kernels, the WGSL printer
/// and the exports' code printers (`nsrm-export`'s DCTL) derive from.
pub mod pixel {
    pub use crate::model::pixel::{Program, Step};
    pub use crate::model::terms::{term_factors, term_name, terms, Term};
}

// Dual-illuminant profiles: two models interpolated by the frame's white, as DNG does.
pub use model::dual_illuminant::{
    invert as invert_model, Calibration, Combination, FrameWhite, Profile,
};

// The CPU frame kernels: a model prepared once and applied to many frames, on chosen threads.
pub use model::fast::{FastError, FastModel, Threads, CHUNK_PIXELS};
pub use model::highlights::{FrameHighlights, HighlightMode, Highlights, HighlightsF32};

// Colorimetry: Lab, ΔE00, output spaces, the output and preview matrices, correlated colour
// temperatures and chromatic adaptation.
pub use colorimetry::output::srgb8;
pub use colorimetry::output::{output_matrix, srgb_oetf, to_linear_srgb};
pub use colorimetry::spaces::{apply as apply_mat3, Mat3, OutputSpace, IDENTITY as MAT3_IDENTITY};
pub use colorimetry::spaces::{
    invert as invert_mat3, mul as mul_mat3, try_invert as try_invert_mat3,
};
pub use colorimetry::spaces::{rgb_to_xyz as primaries_to_xyz, xy_to_xyz};
pub use colorimetry::temperature::temperature_xy;
pub use colorimetry::temperature::{
    bradford_between, cct, dng_weight, neutral_to_xy, TemperatureError, D50_XY,
};
pub use colorimetry::{ciede2000, delta_e00_xyz, xyz_to_lab, D65_WHITE_XYZ};
pub use colorimetry::{lab_to_xyz, xyy_to_xyz};

// Spectral simulation: camera × illuminant × reflectances on a wavelength grid.
pub use spectral::{display_name, simulate, white_xyz, Camera, Illuminant, Reflectances};
pub use spectral::{simulate_named, Grid, SpectralError};

// Training sets: patches with camera RGB and reference XYZ, and their white.
pub use training::{d50_white, fmt_white, parse_white, resolve_patch, white_line};
pub use training::{CaptureProvenance, Provenance, TrainingError, TrainingSet};

// Evaluation: leave-one-out and in-sample ΔE00 statistics, and the paper's Fig. 1.
#[cfg(feature = "plot")]
pub use eval::plot;
pub use eval::{evaluate, evaluate_with, EvalResult, PatchError, Protocol, Stats};
