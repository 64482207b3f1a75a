//! The integration tests, one binary: each module is one file of tests/all/, gated by the cargo
//! features it needs. `common` holds what they share.

#[cfg(feature = "cli")]
mod apply;
mod architecture;
#[cfg(feature = "cli")]
mod calibrate;
#[cfg(feature = "cli")]
mod capture_lib;
#[cfg(feature = "cli")]
mod chart_real;
mod ciede2000_sharma;
#[cfg(feature = "cli")]
mod cli_chart;
#[cfg(feature = "cli")]
mod cli_eval_fit;
#[cfg(feature = "cli")]
mod cli_fit_variants;
mod common;
#[cfg(feature = "cli")]
mod export_ocio;
#[cfg(feature = "io")]
mod exr_fast;
#[cfg(feature = "cli")]
mod farm;
mod farm_jobs;
#[cfg(feature = "cli")]
mod first_hour;
#[cfg(feature = "cli")]
mod fit_apply_agree;
mod fit_hostile;
#[cfg(feature = "cli")]
mod fit_two_illuminants;
mod fit_variants;
#[cfg(feature = "cli")]
mod gpu_export;
#[cfg(feature = "cli")]
mod harden_commands;
#[cfg(feature = "io")]
mod harden_fuzz;
#[cfg(feature = "cli")]
mod harden_inputs;
#[cfg(feature = "cli")]
mod harden_numbers;
#[cfg(feature = "cli")]
mod harden_outputs;
#[cfg(feature = "cli")]
mod harden_signals;
#[cfg(feature = "cli")]
mod harden_tiff;
#[cfg(feature = "cli")]
mod hostile_exr;
#[cfg(feature = "cli")]
mod icc;
#[cfg(feature = "io")]
mod io;
mod model_properties;
mod paper_table1;
mod parsers_fuzz;
#[cfg(feature = "gpu")]
mod pixel_policy;
#[cfg(feature = "cli")]
mod profiles;
#[cfg(feature = "cli")]
mod profiles_rawtherapee;
mod raw;
#[cfg(feature = "raw")]
mod raw_xtrans;
#[cfg(feature = "cli")]
mod readme;
#[cfg(feature = "studio")]
mod studio;
#[cfg(feature = "cli")]
mod white;
#[cfg(feature = "cli")]
mod white_as_shot;
