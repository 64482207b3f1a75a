//! `nsrm studio`: a local calibration studio. A small HTTP server on 127.0.0.1 serves one page
//! (embedded in the binary) and the JSON API that page uses; every number and file it shows is
//! computed by the same code as `chart extract`, `fit`, `eval` and `export`.
//!
//! Safety on a shared workstation: loopback only; a random per-run token on every request (in
//! the printed URL, as Jupyter does); a `Host` (and any `Origin`) of localhost, or 403 (DNS
//! rebinding, cross-site requests); uploads bounded by the frame limits of the CLI and streamed
//! to a per-run temporary directory, the only place the server writes (removed on exit and on
//! SIGINT/SIGTERM/SIGHUP); frames are read only from the paths given on the command line or
//! uploaded, never from a path in a request.

mod http;
mod server;
mod session;
mod wire;

use super::common::UsageError;
use anyhow::{Context, Result};
use http::Reply;
use session::Studio;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Frames the page may open (whatever `chart extract` reads), or directories of them.
    #[arg(value_name = "DIR|FILE")]
    inputs: Vec<PathBuf>,
    /// The port on 127.0.0.1 (default: one the system picks).
    #[arg(long, default_value_t = 0)]
    port: u16,
    /// Print the URL only; do not open a browser.
    #[arg(long)]
    no_browser: bool,
    #[command(flatten)]
    max_pixels: super::values::MaxPixelsArg,
    /// Where the server computes corrected previews: auto (a hardware GPU if there is one, else
    /// the CPU; a software rasteriser such as lavapipe is slower than the CPU path), gpu (any
    /// adapter, software ones included) or cpu. As in `apply`.
    #[arg(long, value_enum, ignore_case = true, default_value_t = nsrm::gpu::DeviceChoice::Auto)]
    device: nsrm::gpu::DeviceChoice,
    /// Requests computed at once (each connection is read on a thread of its own, at most 64;
    /// a request takes one of these once its headers and small body are in).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u64).range(1..=64))]
    threads: u64,
}

const STOP_SIGNALS: [i32; 3] = [
    signal_hook::consts::SIGINT,
    signal_hook::consts::SIGTERM,
    signal_hook::consts::SIGHUP,
];

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let files = if a.inputs.is_empty() {
        Vec::new()
    } else {
        nsrm_io::batch::expand_inputs(&a.inputs).context("the frames to open")?
    };
    let listener = std::net::TcpListener::bind(("127.0.0.1", a.port)).map_err(|e| {
        UsageError(format!(
            "--port {}: cannot listen on 127.0.0.1: {e}",
            a.port
        ))
    })?;
    let port = listener
        .local_addr()
        .map(|s| s.port())
        .context("the server's address")?;
    let signal = Arc::new(AtomicUsize::new(0));
    for sig in STOP_SIGNALS {
        signal_hook::flag::register_usize(sig, Arc::clone(&signal), sig as usize)
            .context("installing the signal handlers")?;
    }
    let studio = Arc::new(Studio::new(
        files,
        port,
        a.max_pixels.max_pixels,
        a.device,
        a.threads as usize,
    )?);
    let url = format!("http://127.0.0.1:{port}/?token={}", studio.token);
    println!("nsrm studio: {url}");
    println!(
        "nsrm studio: {} frame(s) listed; temporary files in {}; Ctrl-C to stop",
        studio.files.len(),
        studio.tmp.display()
    );
    if !a.no_browser {
        open_browser(&url);
    }
    let handler = Arc::clone(&studio);
    let handle: Arc<dyn Fn(server::Request) + Send + Sync> =
        Arc::new(move |req| http::serve(&handler, req));
    std::thread::Builder::new()
        .name("nsrm-studio-accept".into())
        .spawn(move || server::accept_loop(listener, handle))
        .context("starting the server's thread")?;
    // The main thread waits for a signal; the connections are served until the process ends.
    while signal.load(Ordering::SeqCst) == 0 {
        std::thread::sleep(Duration::from_millis(100));
    }
    let sig = signal.load(Ordering::SeqCst);
    studio.cleanup();
    eprintln!("nsrm studio: stopped (signal {sig}); temporary files removed");
    Ok(ExitCode::from((128 + sig).min(255) as u8))
}

/// Opens `url` in the desktop's browser, if there is one (failure is only reported).
fn open_browser(url: &str) {
    let opener = if cfg!(target_os = "macos") {
        "open"
    } else {
        "xdg-open"
    };
    match std::process::Command::new(opener)
        .arg(url)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
    {
        Ok(_) => {}
        Err(e) => eprintln!("nsrm studio: could not start {opener} ({e}); open the URL above"),
    }
}

/// A JSON reply: one of the answers of [`wire`].
fn json(status: u16, v: &impl serde::Serialize) -> Reply {
    Reply::new(
        status,
        "application/json",
        serde_json::to_vec(v).unwrap_or_default(),
    )
}
