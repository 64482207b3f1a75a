//! The `nsrm` command line: argument parsing and dispatch over the `nsrm` corrector's public API.
//! Each subcommand lives in its own file; flags are documented once (their doc comments) and clap
//! turns them into `--help`. The farm files (`farmlib`) and the calibration studio (`studio`,
//! feature `studio`) are modules of this crate. Its one public item is [`main`], the binary's
//! entry point.
//!
//! Exit status: 0 success, 1 failure (a message with its context on stderr), 2 usage error.
//!
//! A closed pipe ends nothing: `println!`, `print!`, `eprintln!` and `eprint!` are shadowed here
//! (before every subcommand's module, so all of them use these) by versions that drop what the
//! reader no longer takes (`nsrm export … | head -1`, `nsrm apply … 2>&1 | head -1`) instead
//! of panicking; the command goes on, its outputs are committed, and its exit status is that of
//! its work. (The standard macros panic on a write error, and the panic hook's own message to a
//! closed stderr then aborted the process.)
#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![warn(missing_docs)]

/// `println!` that a closed standard output does not end.
macro_rules! println {
    () => { $crate::say(false, format_args!("\n")) };
    ($($t:tt)*) => { $crate::say(false, format_args!("{}\n", format_args!($($t)*))) };
}
/// `print!` that a closed standard output does not end.
#[allow(unused_macros)]
macro_rules! print {
    ($($t:tt)*) => { $crate::say(false, format_args!($($t)*)) };
}
/// `eprintln!` that a closed standard error does not end.
macro_rules! eprintln {
    () => { $crate::say(true, format_args!("\n")) };
    ($($t:tt)*) => { $crate::say(true, format_args!("{}\n", format_args!($($t)*))) };
}
/// `eprint!` that a closed standard error does not end.
#[allow(unused_macros)]
macro_rules! eprint {
    ($($t:tt)*) => { $crate::say(true, format_args!($($t)*)) };
}

/// Writes `args` to standard error (`err`) or output; a write that fails (a closed pipe, a full
/// disk behind a redirection) is dropped: the message is lost, not the command's work.
pub(crate) fn say(err: bool, args: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let _ = if err {
        std::io::stderr().lock().write_fmt(args)
    } else {
        std::io::stdout().lock().write_fmt(args)
    };
}

mod apply;
mod bench;
mod bench_aids;
mod calibrate;
mod calibrate_report;
mod capture;
mod chart;
mod combine;
mod common;
mod errors;
mod eval;
mod export;
mod export_shader;
mod farm;
mod farmlib;
mod fit;
mod fit_args;
mod help;
mod outputs;
mod progress;
mod render_chart;
mod render_scene;
mod runtime_dir;
#[cfg(feature = "studio")]
mod studio;
mod terms;
mod values;
mod white;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

/// Camera colour correction: fit LRM / PRM / RPRM / NSRM models on chart spectra or measured
/// patches, evaluate them as the NSRM paper does, and apply them to linear raw frames on the GPU.
#[derive(Debug, Parser)]
#[command(name = "nsrm", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Colour-correct frames with a model file (batch, GPU or CPU): camera raw files (DNG, CR2,
    /// CR3, NEF, ARW, RAF, ORF, RW2, …) and linear EXR or TIFF.
    Apply(apply::Args),
    /// Per-pixel throughput of each model on the CPU (one thread, all threads) and the GPU, as a
    /// fraction of a memcpy of the same bytes.
    Bench(bench::Args),
    /// One chart shot to a calibrated result: `nsrm calibrate SHOT -o DIR` finds and reads the
    /// chart, diagnoses the shot, fits (the best by leave-one-out, or --kind), and writes the
    /// model, the patches, the overlay and a report (text and HTML); --export dcp,icc,… adds
    /// the profiles.
    Calibrate(calibrate::Args),
    /// Read a photographed chart: `nsrm chart extract FRAME --chart cc24|sg|spyder24|auto -o patches.csv`;
    /// `nsrm chart rate` measures detection on synthetic scenes.
    #[command(subcommand)]
    Chart(chart::Command),
    /// Combine two model files fitted under two illuminants (e.g. StdA and D65) into one
    /// two-illuminant model, interpolated by each frame's white as a DNG profile is.
    Combine(combine::Args),
    /// Leave-one-out (or in-sample) ΔE00 of the models; without flags, the paper's experiment on
    /// built-in data (D5100, rawtoaces-190, D65/TL865/LED-B5), printed like its Table 1.
    Eval(eval::Args),
    /// Export a model for grading and compositing tools: a CLF, a .cube or an OpenColorIO v2
    /// config, with its measured approximation error.
    Export(export::Args),
    /// Write a self-contained compute shader (WGSL, GLSL, HLSL, MSL or SPIR-V) with a model's
    /// matrix baked in.
    ExportShader(export_shader::Args),
    /// Batches on farm engines: job files for Open Job Description (Deadline Cloud), Slurm and
    /// Kubernetes; `farm run` (one retry-safe shard with its manifest); `farm verify`.
    #[command(subcommand)]
    Farm(Box<farm::Command>),
    /// Fit one model and write it as a JSON model file.
    Fit(fit::Args),
    /// List the terms of a model kind and order (the single definition the shaders use).
    Terms(terms::Args),
    /// Render a synthetic linear camera-RGB chart frame (EXR/TIFF) with its patch layout.
    RenderChart(render_chart::Args),
    /// Render a synthetic photo of a CC24 or SG chart (pose, clutter, uneven light, blur, noise)
    /// with its ground truth.
    RenderScene(render_scene::Args),
    /// A local calibration studio in the browser: open a frame, fix the chart reading, fit,
    /// compare and export (serves on 127.0.0.1 with a per-run token).
    #[cfg(feature = "studio")]
    Studio(studio::Args),
}

/// Parses the command line, runs the subcommand, and maps errors to exit codes.
pub fn main() -> ExitCode {
    // A decoder's panic is contained per file by the library (reported as that file's error);
    // this hook keeps its message to one line. An uncontained panic still exits 101.
    // A panic inside the camera-raw decoder (rawler) is contained the same way and says nothing
    // here: the file's error names it.
    std::panic::set_hook(Box::new(|info| {
        if info
            .location()
            .is_some_and(|l| l.file().contains("rawler-") || l.file().contains("/rawler/"))
        {
            return;
        }
        let what = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("nsrm: internal error{at}: {what}");
    }));
    let parsed = help::command(Cli::command())
        .try_get_matches()
        .and_then(|m| Cli::from_arg_matches(&m));
    let cli = match parsed {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    // Before any thread starts: Mesa's loader complains on every GPU run without it, and more
    // commands than `apply` open the GPU (`farm run`, the studio, exports that validate).
    runtime_dir::ensure_runtime_dir();
    let result = match cli.command {
        Command::Apply(a) => apply::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Chart(c) => chart::run(c),
        Command::Combine(a) => combine::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Export(a) => export::run(a),
        Command::ExportShader(a) => export_shader::run(a),
        Command::Farm(c) => farm::run(*c),
        Command::Fit(a) => fit::run(a),
        Command::Terms(a) => terms::run(a),
        Command::RenderChart(a) => render_chart::run(a),
        Command::RenderScene(a) => render_scene::run(a),
        #[cfg(feature = "studio")]
        Command::Studio(a) => studio::run(a),
    };
    // A stop signal ends the process with 128 + the signal, whatever the work returned.
    outputs::defer_to_signal_thread();
    match result {
        Ok(code) => code,
        Err(e) => {
            // The library names no flags; the binary says which one is at fault or the way out.
            let (msg, hint) = common::explain(&e);
            // The style of clap's own errors (`error: …`, then an indented hint, as clap gives its `tip:`), so every failure
            // of the command reads alike.
            eprintln!("error: {msg}");
            if let Some(hint) = hint {
                eprintln!("\n  hint: {hint}");
            }
            if e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<nsrm_output::WriteError>(),
                    Some(nsrm_output::WriteError::Exists(_))
                )
            }) {
                eprintln!("\n  hint: pass --overwrite to replace it");
            }
            // A usage error of the binary's own, or of the library (which knows which of its
            // errors are the caller's mistake), anywhere in the context chain.
            let usage = e
                .chain()
                .any(|c| c.downcast_ref::<common::UsageError>().is_some() || errors::is_usage(c));
            if usage {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// Every subcommand, with its path (`nsrm chart rate`).
    fn commands(c: &clap::Command, path: String, out: &mut Vec<(String, clap::Command)>) {
        out.push((path.clone(), c.clone()));
        for s in c.get_subcommands() {
            commands(s, format!("{path} {}", s.get_name()), out);
        }
    }

    /// Every example printed after a command's help parses as that command, and every command
    /// has examples.
    #[test]
    fn every_example_parses_and_every_command_has_some() {
        let cmd = help::command(Cli::command());
        for (path, lines) in help::EXAMPLES {
            for line in *lines {
                let words: Vec<&str> = line.split_whitespace().collect();
                let m = cmd
                    .clone()
                    .try_get_matches_from(&words)
                    .unwrap_or_else(|e| panic!("{line}: {e}"));
                let mut got = Vec::new();
                let mut at = &m;
                while let Some((name, sub)) = at.subcommand() {
                    got.push(name);
                    at = sub;
                }
                assert_eq!(got.join(" "), *path, "{line}");
                Cli::from_arg_matches(&m).unwrap_or_else(|e| panic!("{line}: {e}"));
            }
        }
        let mut all = Vec::new();
        commands(&cmd, String::new(), &mut all);
        for (path, c) in &all {
            let path = path.trim();
            if c.get_subcommands().next().is_some() || c.get_name() == "help" || path.is_empty() {
                continue;
            }
            assert!(
                help::EXAMPLES.iter().any(|(p, _)| *p == path),
                "nsrm {path} has no examples"
            );
        }
    }

    /// `-h` fits on a screen (60 lines of 100 columns) for every command; `--help` says more.
    #[test]
    fn short_help_fits_on_a_screen() {
        let mut all = Vec::new();
        commands(&help::command(Cli::command()), "nsrm".into(), &mut all);
        for (path, c) in &all {
            let mut c = c.clone().term_width(100);
            let short = c.render_help().to_string();
            let long = c.render_long_help().to_string();
            let n = short.lines().count();
            assert!(n <= 60, "{path} -h is {n} lines:\n{short}");
            if c.get_arguments().count() > 3 {
                assert!(
                    long.len() > short.len(),
                    "{path}: --help says no more than -h"
                );
            }
        }
    }

    #[test]
    fn every_flag_has_help_text() {
        let mut all = Vec::new();
        commands(&Cli::command(), "nsrm".into(), &mut all);
        let mut missing = Vec::new();
        for (path, c) in &all {
            for a in c.get_arguments() {
                let id = a.get_id().as_str();
                if matches!(id, "help" | "version") || a.is_hide_set() {
                    continue;
                }
                if a.get_help().is_none() && a.get_long_help().is_none() {
                    missing.push(format!("{path} {id}"));
                }
            }
        }
        assert!(missing.is_empty(), "flags without help text: {missing:?}");
    }

    /// The help of every command that reads frames names every input type it accepts (issue 36:
    /// `apply` said EXR/TIFF, `eval --capture` "linear frame (EXR/TIFF)", though both read raw).
    #[test]
    fn help_texts_name_every_input_type() {
        let mut cli = Cli::command();
        for (path, jpeg) in [
            (&["apply"][..], false),
            (&["fit"], true),
            (&["eval"], true),
            (&["chart", "extract"], true),
            (&["calibrate"], true),
        ] {
            let mut c = &mut cli;
            for p in path {
                c = c.find_subcommand_mut(p).expect("a subcommand");
            }
            let help = c.render_long_help().to_string();
            let mut want = vec!["raw", "DNG", "EXR", "TIFF"];
            if jpeg {
                want.push("JPEG");
            }
            for w in want {
                assert!(
                    help.contains(w),
                    "nsrm {} --help does not say {w}",
                    path.join(" ")
                );
            }
            assert!(!help.contains("linear frame (EXR/TIFF)"), "{help}");
        }
    }

    /// One vocabulary: `--model` is a model file wherever it appears (the kind is `--kind`), and
    /// `-o` is `--output` everywhere.
    #[test]
    fn one_meaning_per_flag() {
        let mut all = Vec::new();
        commands(&Cli::command(), "nsrm".into(), &mut all);
        for (path, c) in &all {
            for a in c.get_arguments() {
                if a.get_long() == Some("model") {
                    let v = a.get_value_names().map(|v| v.join(" ")).unwrap_or_default();
                    assert_eq!(v, "FILE", "{path} --model");
                }
                if a.get_short() == Some('o') {
                    assert_eq!(a.get_long(), Some("output"), "{path} -o");
                }
            }
        }
        // The old spellings still parse (hidden aliases).
        for old in [
            &["nsrm", "fit", "--model", "prm", "-o", "m.json"][..],
            &["nsrm", "terms", "--model", "rprm"],
            &["nsrm", "eval", "--models", "lrm"],
            &["nsrm", "bench", "--models", "lrm"],
            &["nsrm", "chart", "rate", "--chart", "cc24", "--stops", "3"],
            &[
                "nsrm",
                "apply",
                "--model",
                "m.json",
                "--output-dir",
                "d",
                "x.exr",
            ],
        ] {
            assert!(Cli::try_parse_from(old).is_ok(), "{old:?}");
        }
        let new = Cli::try_parse_from(["nsrm", "fit", "--kind", "prm", "-o", "m.json"]).unwrap();
        let Command::Fit(f) = new.command else {
            panic!()
        };
        assert_eq!(f.kind(), nsrm::Kind::Prm);
    }
}
