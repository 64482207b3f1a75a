//! The integration tests, one binary: each module is one file of tests/all/; a test target of the
//! `nsrm-cli` package (it runs the `nsrm` binary). `common` holds what they share.
//!
//! The tests are scenarios that read top to bottom (run the binary, read its files, judge them
//! with another program), so the 120-line limit on functions is the library's, not theirs.
#![allow(clippy::too_many_lines)]

mod apply;
mod architecture;
mod calibrate;
mod capture_lib;
mod chart_real;
mod ciede2000_sharma;
mod cli_chart;
mod cli_eval_fit;
mod cli_fit_variants;
mod common;
mod export_light;
mod export_ocio;
mod exr_fast;
mod farm;
mod farm_jobs;
mod first_hour;
mod fit_apply_agree;
mod fit_hostile;
mod fit_two_illuminants;
mod fit_variants;
mod gpu_export;
mod harden_commands;
mod harden_fuzz;
mod harden_inputs;
mod harden_numbers;
mod harden_outputs;
mod harden_signals;
mod harden_tiff;
mod highlights;
mod hostile_exr;
mod icc;
mod io;
mod model_properties;
mod paper_table1;
mod parsers_fuzz;
mod pixel_policy;
mod profiles;
mod profiles_rawtherapee;
mod python;
mod raw;
mod raw_xtrans;
mod readme;
#[cfg(feature = "studio")]
mod studio;
mod table1_oracle;
mod white;
mod white_as_shot;
