//! The batch executor: a plan's frames through decode → correct → encode, on threads joined by
//! bounded channels so the stages overlap and at most a few frames are held in memory.
//!
//! `workers` decode threads take the next frame to convert (when a permit is free) and decode
//! it; the caller's thread corrects each decoded frame with its [`Correct`] (the GPU engine
//! takes `&mut`, so one thread drives it); `workers` encode threads write each frame and its
//! preview together through the caller's [`FrameSink`]. Frames alive at once (decoding, queued,
//! correcting, encoding) are `workers + 1`, so peak memory stays under `workers + 2` decoded
//! frames; the buffers of written frames are reused by the next decodes ([`FramePool`]).
//!
//! The executor prints nothing: what happens is told to the caller's event callback
//! ([`Event`]), from any of the threads, and returned ([`Executed`]). A stop flag the caller
//! sets (from its signal handler) stops it cleanly: no new frame is started, frames being
//! decoded or corrected are dropped, a frame being written is aborted when the sink says so
//! ([`FrameSink::is_aborted`]: the `nsrm` command's output session sets its abort flag from the
//! same signal), and those frames are left out of the outcomes (not attempted).

use super::batch::{BatchPlan, Job};
use super::{preview, Decoded, FramePool, IoError, ReadOptions, WriteOptions, WriteSeek};
use nsrm::{FastModel, FrameHighlights, Highlights, Mat3, Model, ModelError, Threads};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Why a frame could not be corrected.
#[derive(Debug, thiserror::Error)]
pub enum CorrectError {
    /// The frame's highlight policy could not be built (its clip level, or no neutral of the
    /// models to clip to).
    #[error(transparent)]
    Highlights(#[from] ModelError),
    /// The GPU engine failed.
    #[cfg(feature = "gpu")]
    #[error(transparent)]
    Gpu(#[from] nsrm::gpu::GpuError),
    /// A caller's corrector failed: its message (its causes included).
    #[error("{0}")]
    Other(String),
}

/// Why one frame of a batch failed.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// Reading or decoding the input.
    #[error("{0}")]
    Read(IoError),
    /// Readying the correction for the frame ([`Correct::prepare`]).
    #[error("{}: {source}", input.display())]
    Prepare {
        /// The input.
        input: std::path::PathBuf,
        /// The corrector's error.
        source: CorrectError,
    },
    /// Correcting the frame ([`Correct::correct`]).
    #[error("{}: correcting: {source}", input.display())]
    Correct {
        /// The input.
        input: std::path::PathBuf,
        /// The corrector's error.
        source: CorrectError,
    },
    /// Encoding or committing the output or its preview.
    #[error("{0}")]
    Write(IoError),
}

/// The correction step of a batch, driven from one thread (the caller's).
pub trait Correct {
    /// What corrects, in words (`CPU (avx2 kernel)`, `GPU NVIDIA H100`).
    fn describe(&self) -> String;

    /// Readies the correction for one decoded frame (a model set combined for its white, say);
    /// returns a line worth telling (a white not seen before), if any.
    fn prepare(&mut self, frame: &Decoded) -> Result<Option<String>, CorrectError>;

    /// Corrects the frames of `frame` in place, the highlight policy `highlights` makes of
    /// the frame run before the model.
    fn correct(
        &mut self,
        frame: &mut Decoded,
        highlights: &FrameHighlights,
    ) -> Result<(), CorrectError>;
}

/// One model (its output space folded in) applied to every frame: on the CPU (the fast f32
/// kernels, rebuilt when a frame's highlight policy differs from the last one's) or with the
/// GPU engine.
#[derive(Debug)]
pub struct ModelCorrector {
    model: Model,
    how: How,
}

#[derive(Debug)]
enum How {
    Cpu(Box<FastModel>, Option<Highlights>),
    #[cfg(feature = "gpu")]
    Gpu(Box<nsrm::gpu::Engine>),
}

impl ModelCorrector {
    /// `model` on the CPU, on every core.
    pub fn cpu(model: Model) -> ModelCorrector {
        let fast = Box::new(FastModel::new(&model));
        ModelCorrector {
            model,
            how: How::Cpu(fast, None),
        }
    }

    /// `model` on the GPU `engine`.
    #[cfg(feature = "gpu")]
    pub fn gpu(model: Model, engine: Box<nsrm::gpu::Engine>) -> ModelCorrector {
        ModelCorrector {
            model,
            how: How::Gpu(engine),
        }
    }
}

impl Correct for ModelCorrector {
    fn describe(&self) -> String {
        match &self.how {
            How::Cpu(f, _) => format!("CPU ({} kernel)", f.kernel_name()),
            #[cfg(feature = "gpu")]
            How::Gpu(e) => format!("GPU {}", e.adapter_name()),
        }
    }

    fn prepare(&mut self, _frame: &Decoded) -> Result<Option<String>, CorrectError> {
        Ok(None)
    }

    fn correct(
        &mut self,
        frame: &mut Decoded,
        highlights: &FrameHighlights,
    ) -> Result<(), CorrectError> {
        let policy = highlights.policy(frame.camera().and_then(|c| c.clip_level), None)?;
        #[cfg(feature = "gpu")]
        let with_policy = || self.model.clone().with_policy(policy);
        for f in frame.frames_mut() {
            match &mut self.how {
                How::Cpu(fast, built) => {
                    if *built != policy {
                        **fast = FastModel::new(&self.model.clone().with_policy(policy));
                        *built = policy;
                    }
                    fast.apply(f, Threads::All)
                }
                #[cfg(feature = "gpu")]
                How::Gpu(e) => e.apply(&with_policy(), f)?,
            }
        }
        Ok(())
    }
}

/// One file's encoder for a [`FrameSink`]: writes the file's bytes into the writer it is given
/// (called at most once).
pub type Encoder<'a> = Box<dyn FnOnce(&mut dyn WriteSeek) -> Result<(), IoError> + Send + 'a>;

/// Where a batch puts each frame's files: the output and its preview are handed over together,
/// so a sink that stages files can make them appear together or not at all. The `nsrm` command's
/// output session (crate `nsrm-output`) is one: it stages each file in a temporary beside its
/// destination and commits a frame's files as one unit; [`Files`] writes them directly.
pub trait FrameSink: Sync {
    /// Writes one frame's files, `(destination, encoder)` each, in order. An error is the
    /// frame's failure (the batch goes on with `continue_on_error`).
    fn write_together(&self, files: Vec<(&Path, Encoder<'_>)>) -> Result<(), IoError>;

    /// Whether the sink was stopped (a signal): a frame whose write failed then is reported as
    /// aborted, not failed. The default: never.
    fn is_aborted(&self) -> bool {
        false
    }
}

/// The simplest [`FrameSink`]: each file created at its destination and written in place, with
/// no staging. An existing file is refused unless `overwrite` is set; a frame that fails may
/// leave a partial file (a sink that stages, such as the `nsrm` command's, does not).
#[derive(Debug, Clone, Copy, Default)]
pub struct Files {
    /// Replace existing files.
    pub overwrite: bool,
}

impl FrameSink for Files {
    fn write_together(&self, files: Vec<(&Path, Encoder<'_>)>) -> Result<(), IoError> {
        for (dest, encode) in files {
            let io = |err| IoError::Write {
                path: dest.to_path_buf(),
                err,
            };
            let file = if self.overwrite {
                std::fs::File::create(dest)
            } else {
                std::fs::File::create_new(dest)
            }
            .map_err(io)?;
            let mut w = std::io::BufWriter::new(file);
            encode(&mut w)?;
            std::io::Write::flush(&mut w).map_err(io)?;
        }
        Ok(())
    }
}

/// A batch run's settings.
pub struct ExecOptions<'a> {
    /// Where each frame's output and preview go.
    pub sink: &'a dyn FrameSink,
    /// How inputs are read.
    pub read: ReadOptions,
    /// How outputs are written.
    pub write: WriteOptions,
    /// What each frame's clipped highlights become.
    pub highlights: FrameHighlights,
    /// Corrected output to linear sRGB, for the previews.
    pub to_srgb: Mat3,
    /// Decode and encode threads (each holds a frame); at least 1.
    pub workers: usize,
    /// Go on after a frame fails; else no frame is started after the first failure.
    pub continue_on_error: bool,
    /// Set by the caller (its signal handler) to stop the run.
    pub stop: &'a AtomicBool,
}

impl std::fmt::Debug for ExecOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExecOptions")
            .field("read", &self.read)
            .field("write", &self.write)
            .field("highlights", &self.highlights)
            .field("workers", &self.workers)
            .field("continue_on_error", &self.continue_on_error)
            .finish_non_exhaustive()
    }
}

/// What happens during a run, told as it happens (from any of its threads).
#[derive(Debug, Clone, Copy)]
#[non_exhaustive]
pub enum Event<'a> {
    /// Frame `index` (of the plan's jobs) is being read.
    Started {
        /// The job's index.
        index: usize,
        /// Its input.
        input: &'a Path,
    },
    /// Frame `index` was decoded from a camera raw file of this camera (`make model`).
    Camera {
        /// The job's index.
        index: usize,
        /// Its input.
        input: &'a Path,
        /// The camera.
        camera: &'a str,
    },
    /// The corrector's line about frame `index` ([`Correct::prepare`]).
    Note {
        /// The job's index.
        index: usize,
        /// The line.
        text: &'a str,
    },
    /// Frame `index` is written and committed.
    Done {
        /// The job's index.
        index: usize,
        /// Its output.
        output: &'a Path,
        /// Its pixels.
        pixels: usize,
        /// Pixels written per second since the run started.
        pixels_per_second: f64,
    },
    /// Frame `index` failed.
    Failed {
        /// The job's index.
        index: usize,
        /// Its input.
        input: &'a Path,
        /// Why.
        error: &'a FrameError,
    },
    /// Frame `index` was being written when the run was stopped: nothing of it committed.
    Aborted {
        /// The job's index.
        index: usize,
        /// Its output.
        output: &'a Path,
    },
}

/// What happened to one frame the run started.
#[derive(Debug)]
pub enum FrameOutcome {
    /// Written and committed.
    Converted {
        /// Its pixels.
        pixels: usize,
    },
    /// Being written when the run was stopped: its temporary removed, nothing committed.
    Aborted,
    /// Failed.
    Failed(FrameError),
}

/// Time spent in each stage (decode and encode summed over their threads) and what was
/// written.
#[derive(Debug, Default, Clone, Copy)]
pub struct Timing {
    /// Decoding.
    pub decode: Duration,
    /// Correcting.
    pub correct: Duration,
    /// Encoding and committing.
    pub encode: Duration,
    /// Pixels written.
    pub pixels: usize,
    /// Frames written.
    pub frames: usize,
}

/// A run's result.
#[derive(Debug, Default)]
pub struct Executed {
    /// Each started frame's outcome, by job index, in the order they ended; frames not started
    /// (after a stop, or the first failure without `continue_on_error`) are not listed.
    pub outcomes: Vec<(usize, FrameOutcome)>,
    /// Where the time went.
    pub timing: Timing,
}

/// Runs the frames of `plan` to convert through decode → `corrector` → encode with `opts`,
/// telling `on_event` what happens. Prints nothing; stops cleanly when `opts.stop` is set.
pub fn execute(
    plan: &BatchPlan,
    corrector: &mut dyn Correct,
    opts: &ExecOptions<'_>,
    on_event: &(dyn Fn(Event<'_>) + Sync),
) -> Executed {
    let todo = plan.to_convert();
    let workers = opts.workers.max(1);
    let p = Pipeline {
        jobs: &plan.jobs,
        todo: &todo,
        s: opts,
        on_event,
        halt: AtomicBool::new(false),
        next: AtomicUsize::new(0),
        results: Mutex::new(Vec::new()),
        timing: Mutex::new(Timing::default()),
        started: Instant::now(),
        permits: Permits::new(workers + 1),
        pool: FramePool::new(workers + 1),
    };
    let p = &p;
    std::thread::scope(|scope| {
        let (dec_tx, dec_rx) = sync_channel::<(usize, Decoded)>(workers);
        let (enc_tx, enc_rx) = sync_channel::<(usize, Decoded)>(workers);
        let enc_rx = Arc::new(Mutex::new(enc_rx));
        for _ in 0..workers {
            let tx = dec_tx.clone();
            scope.spawn(move || p.decode_loop(tx));
        }
        drop(dec_tx);
        for _ in 0..workers {
            let rx = Arc::clone(&enc_rx);
            scope.spawn(move || p.encode_loop(&rx));
        }
        p.correct_loop(dec_rx, enc_tx, corrector);
    });
    let outcomes = std::mem::take(&mut *lock(&p.results));
    let timing = *lock(&p.timing);
    Executed { outcomes, timing }
}

/// What the reader, corrector and writer threads of one run share.
struct Pipeline<'a> {
    jobs: &'a [Job],
    todo: &'a [usize],
    s: &'a ExecOptions<'a>,
    on_event: &'a (dyn Fn(Event<'_>) + Sync),
    /// Set by the first failure without `continue_on_error`: no more frames are started.
    halt: AtomicBool,
    /// The next index into `todo` to read.
    next: AtomicUsize,
    results: Mutex<Vec<(usize, FrameOutcome)>>,
    timing: Mutex<Timing>,
    started: Instant,
    permits: Permits,
    pool: FramePool,
}

impl Pipeline<'_> {
    fn stopped(&self) -> bool {
        self.s.stop.load(Ordering::SeqCst)
    }

    fn fail(&self, i: usize, error: FrameError) {
        if !self.s.continue_on_error {
            self.halt.store(true, Ordering::SeqCst);
        }
        (self.on_event)(Event::Failed {
            index: i,
            input: &self.jobs[i].input,
            error: &error,
        });
        lock(&self.results).push((i, FrameOutcome::Failed(error)));
    }

    /// A reader thread: takes the next frame to convert (when a permit is free) and decodes it.
    fn decode_loop(&self, tx: SyncSender<(usize, Decoded)>) {
        loop {
            self.permits.acquire();
            if self.halt.load(Ordering::SeqCst) || self.stopped() {
                self.permits.release();
                break;
            }
            let k = self.next.fetch_add(1, Ordering::SeqCst);
            let Some(&i) = self.todo.get(k) else {
                self.permits.release();
                break;
            };
            let input = &self.jobs[i].input;
            (self.on_event)(Event::Started { index: i, input });
            let t = Instant::now();
            match Decoded::read_pooled(input, &self.s.read, &self.pool) {
                Ok(d) => {
                    lock(&self.timing).decode += t.elapsed();
                    if tx.send((i, d)).is_err() {
                        self.permits.release();
                        break;
                    }
                }
                Err(e) => {
                    self.permits.release();
                    self.fail(i, FrameError::Read(e))
                }
            }
        }
    }

    /// A writer thread: encodes corrected frames and records each outcome.
    fn encode_loop(&self, rx: &Mutex<Receiver<(usize, Decoded)>>) {
        loop {
            let msg = lock(rx).recv();
            let Ok((i, d)) = msg else { break };
            if self.stopped() {
                // Not started: left as not attempted.
                drop(d);
                self.permits.release();
                continue;
            }
            let t = Instant::now();
            let pixels = d.pixels();
            let encoded = encode(&self.jobs[i], d, self.s, &self.pool);
            self.permits.release();
            let output = &self.jobs[i].output;
            match encoded {
                Ok(()) => {
                    let mut tm = lock(&self.timing);
                    tm.encode += t.elapsed();
                    tm.pixels += pixels;
                    tm.frames += 1;
                    let secs = self.started.elapsed().as_secs_f64().max(1e-9);
                    let rate = tm.pixels as f64 / secs;
                    drop(tm);
                    lock(&self.results).push((i, FrameOutcome::Converted { pixels }));
                    (self.on_event)(Event::Done {
                        index: i,
                        output,
                        pixels,
                        pixels_per_second: rate,
                    });
                }
                // Stopped while writing: not a failure of the file.
                Err(_) if self.stopped() || self.s.sink.is_aborted() => {
                    lock(&self.results).push((i, FrameOutcome::Aborted));
                    (self.on_event)(Event::Aborted { index: i, output });
                }
                Err(e) => self.fail(i, FrameError::Write(e)),
            }
        }
    }

    /// The correcting thread (the caller's): corrects each decoded frame and passes it on to
    /// the writers.
    fn correct_loop(
        &self,
        dec_rx: Receiver<(usize, Decoded)>,
        enc_tx: SyncSender<(usize, Decoded)>,
        corrector: &mut dyn Correct,
    ) {
        for (i, mut d) in dec_rx {
            if let Some(cam) = d.camera() {
                let camera = cam.camera();
                (self.on_event)(Event::Camera {
                    index: i,
                    input: &d.path,
                    camera: &camera,
                });
            }
            if self.stopped() {
                drop(d);
                self.permits.release();
                continue;
            }
            let input = &self.jobs[i].input;
            match corrector.prepare(&d) {
                Ok(Some(text)) => (self.on_event)(Event::Note {
                    index: i,
                    text: &text,
                }),
                Ok(None) => {}
                Err(source) => {
                    drop(d);
                    self.permits.release();
                    let input = input.clone();
                    self.fail(i, FrameError::Prepare { input, source });
                    continue;
                }
            }
            let t = Instant::now();
            match corrector.correct(&mut d, &self.s.highlights) {
                Ok(()) => {
                    lock(&self.timing).correct += t.elapsed();
                    if enc_tx.send((i, d)).is_err() {
                        self.permits.release();
                        break;
                    }
                }
                Err(source) => {
                    drop(d);
                    self.permits.release();
                    let input = input.clone();
                    self.fail(i, FrameError::Correct { input, source })
                }
            }
        }
    }
}

/// A counting semaphore: how many more frames may be decoded before one is written.
struct Permits {
    free: Mutex<usize>,
    freed: Condvar,
}

impl Permits {
    fn new(n: usize) -> Permits {
        Permits {
            free: Mutex::new(n),
            freed: Condvar::new(),
        }
    }

    fn acquire(&self) {
        let mut free = lock(&self.free);
        while *free == 0 {
            free = self.freed.wait(free).unwrap_or_else(|e| e.into_inner());
        }
        *free -= 1;
    }

    fn release(&self) {
        *lock(&self.free) += 1;
        self.freed.notify_one();
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Writes the output and its preview together: both are staged (encoded into temporaries),
/// then committed as one unit of the run's session, so both appear or neither.
fn encode(job: &Job, d: Decoded, s: &ExecOptions<'_>, pool: &FramePool) -> Result<(), IoError> {
    let png = match &job.preview {
        Some(_) => Some(preview::encode_png(&d.frame, &s.to_srgb)?),
        None => None,
    };
    let output = job.output.as_path();
    let write = &s.write;
    let mut files: Vec<(&Path, Encoder<'_>)> = vec![(
        output,
        Box::new(move |w: &mut dyn WriteSeek| d.write_to_recycling(output, write, w, pool)),
    )];
    if let (Some(path), Some(png)) = (&job.preview, png) {
        let path = path.as_path();
        files.push((
            path,
            Box::new(move |w: &mut dyn WriteSeek| {
                w.write_all(&png).map_err(|err| IoError::Write {
                    path: path.to_path_buf(),
                    err,
                })
            }),
        ));
    }
    s.sink.write_together(files)
}

#[cfg(test)]
#[path = "batch_exec_tests.rs"]
mod tests;
