//! The binary's side of the output session ([`nsrm_output`]): every command opens one with its
//! inputs and outputs before any work, and a signal handler that aborts it. The library's
//! encoders write into the session's staged temporaries (`unit.write_with(dest, |w|
//! frame.write_to(dest, opts, w))`) or hand it bytes (the exports' `render`).
//!
//! ```text
//! let session = outputs::open(a.overwrite, &[&a.model], &[&a.output])?;   // exit 2 on a collision
//! … work …
//! let mut unit = session.unit();
//! unit.write_bytes(&a.output, text.as_bytes())?;  // or `unit.write_with(dest, encoder)`
//! unit.commit()?;                                 // all outputs together, or none
//! ```

use anyhow::{Context, Result};
use nsrm_output::Session;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicI32, Ordering};

/// The session's temporaries found in a batch's output directories (left by a killed run, or
/// being written by another one now), sorted.
pub(crate) fn stale_temporaries(plan: &nsrm_io::batch::BatchPlan) -> Vec<PathBuf> {
    plan.dirs
        .iter()
        .flat_map(|d| nsrm_output::stale_temporaries(d))
        .collect()
}

/// The signals that abort a run, with their names.
pub(crate) const STOP_SIGNALS: [(i32, &str); 3] = [
    (signal_hook::consts::SIGINT, "SIGINT"),
    (signal_hook::consts::SIGTERM, "SIGTERM"),
    (signal_hook::consts::SIGHUP, "SIGHUP"),
];

/// A session for a run that replaces existing outputs when `overwrite`: `inputs` (those that are
/// files; a built-in name that is no file is left out by the caller) and `outputs` declared,
/// which fails (a usage error, exit 2) when an output is an input or another output, and (exit
/// 1, with the hint) when one exists without `overwrite`. Then a signal thread is started: on
/// SIGINT, SIGTERM or SIGHUP it aborts the session (removing every temporary it holds, after a
/// unit being committed is placed or rolled back) and ends the process with 128 + the signal.
pub(crate) fn open(overwrite: bool, inputs: &[&Path], outputs: &[&Path]) -> Result<Session> {
    let mut session = Session::new(overwrite);
    for i in inputs {
        session.input(i)?;
    }
    for o in outputs {
        session.output(o)?;
    }
    exit_on_signal(&session)?;
    Ok(session)
}

/// The signal the signal thread took, once it has taken one (0 before).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// Once a stop signal has come, the signal thread owns the end of the process: the main thread's
/// work fails at its next write ([`nsrm_output::WriteError::Aborted`]), and returning from
/// `main` then would end the process with that error's status (1), perhaps before the thread
/// has removed every temporary. So the main thread calls this before it returns: when a signal
/// has come it waits for the thread's exit (128 + the signal), and exits so itself if the thread
/// has not done it within a few seconds.
pub(crate) fn defer_to_signal_thread() {
    let sig = SIGNAL.load(Ordering::SeqCst);
    if sig == 0 {
        return;
    }
    std::thread::sleep(std::time::Duration::from_secs(10));
    std::process::exit(128 + sig);
}

/// Starts the thread that aborts `session` and exits with 128 + the signal (see [`open`]).
pub(crate) fn exit_on_signal(session: &Session) -> Result<()> {
    let handle = session.abort_handle();
    let mut signals = signal_hook::iterator::Signals::new(STOP_SIGNALS.map(|(s, _)| s))
        .context("installing the signal handlers")?;
    std::thread::Builder::new()
        .name("nsrm-signals".into())
        .spawn(move || {
            if let Some(sig) = signals.forever().next() {
                SIGNAL.store(sig, Ordering::SeqCst);
                let removed = handle.abort();
                let name = STOP_SIGNALS
                    .iter()
                    .find(|(s, _)| *s == sig)
                    .map_or("a signal", |(_, n)| n);
                eprintln!(
                    "nsrm: interrupted by {name}: no output left half-written ({removed} temporary file(s) removed)"
                );
                std::process::exit(128 + sig);
            }
        })
        .context("starting the signal thread")?;
    Ok(())
}

/// `spec` as a path when it names an existing file (a `NAME|FILE` option), for
/// [`Session::input`].
pub(crate) fn file_arg(spec: &str) -> Option<&Path> {
    let p = Path::new(spec);
    p.exists().then_some(p)
}
