//! The output session of the `nsrm` command and the Python package: one value per run that
//! knows the run's inputs and outputs, checks them against each other before any work, stages
//! every output in a temporary file, commits outputs that belong together as one unit, and
//! cleans up after a signal. Nothing here is process-wide.
//!
//! The corrector (`nsrm`) writes nowhere by itself: its encoders take any `Write + Seek`
//! ([`nsrm_io::Decoded::write_to`]) or return bytes (the exports' `render`), and its batch
//! executor hands each frame's files to a [`nsrm_io::batch::FrameSink`]. This crate is the file
//! policy above it: [`Unit::write_with`] gives an encoder a staged temporary, and [`Session`]
//! is a `FrameSink` whose frames commit as one unit each.
//!
//! # How a command uses it
//!
//! ```
//! use nsrm_output::Session;
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let dir = tempfile::tempdir()?;
//! # let model = dir.path().join("m.json");
//! # std::fs::write(&model, "{}")?;
//! let lut = dir.path().join("out/m.cube");
//! let report = dir.path().join("out/m.json");
//! // 1. One session per run; `overwrite` is the run's policy for existing outputs.
//! let mut session = Session::new(false);
//! // 2. Before any work: every input, then every output. An output is resolved (its parent
//! //    directories created, `..` and symbolic links followed) and refused, as a usage error, when
//! //    it is an input (same path, or same device and inode: a hard link), when two outputs are
//! //    one file, or when it exists (without `overwrite`) or is not a regular file.
//! session.input(&model)?;
//! session.output(&lut)?;
//! session.output(&report)?;
//! assert!(session.output(&model).is_err()); // would replace an input
//! // 3. The signal handler holds the session's abort handle: a thread waiting for the signal
//! //    calls `handle.abort()`, which stops every write and removes the run's temporaries.
//! let _handle = session.abort_handle();
//! // 4. The work; then the outputs that belong together are written into one unit (each into a
//! //    fresh temporary beside its destination) and committed together: all appear or none,
//! //    and a file that `overwrite` replaced is put back if a later one fails.
//! let mut unit = session.unit();
//! unit.write_bytes(&lut, b"LUT_3D_SIZE 2\n")?;
//! unit.write_bytes(&report, b"{}")?;
//! unit.commit()?;
//! assert!(lut.exists() && report.exists());
//! # Ok(()) }
//! ```
//!
//! A batch (`apply`) takes one unit per frame from the same session, from several threads
//! ([`Session`] is `Sync`; a [`Unit`] is `Send`): each frame's outputs commit together.
//!
//! # Guarantees
//! * Temporaries are `.NAME.nsrm-PID-RANDOM.tmp` beside their destination (16 random letters and
//!   digits, drawn by the `tempfile` crate), created with `O_EXCL`; a name that exists is never
//!   touched, another is drawn.
//! * Only temporaries this session created are ever removed ([`AbortHandle::abort`],
//!   the session's clean-up, a dropped [`Unit`]).
//! * Nothing but a regular file is ever replaced, even with `overwrite`.
//! * After [`AbortHandle::abort`] (a signal), every write in progress fails at its next buffer
//!   write, no temporary is created and nothing is committed ([`WriteError::Aborted`]); a unit
//!   being committed finishes or is rolled back first (the commit holds the session's lock).

#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![warn(missing_docs)]

use std::collections::BTreeSet;
use std::ffi::OsStr;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

/// Errors from declaring or writing an output.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The destination exists and the session does not overwrite.
    #[error("{}: already exists (not replaced)", .0.display())]
    Exists(PathBuf),
    /// The destination is a directory, FIFO, device or socket.
    #[error("{}: not a regular file (it is {what}); only regular files are ever replaced", path.display())]
    NotRegular {
        /// The destination.
        path: PathBuf,
        /// What it is.
        what: &'static str,
    },
    /// Creating, writing or moving the file failed.
    #[error("{}: cannot write: {err}", path.display())]
    Io {
        /// The destination.
        path: PathBuf,
        /// The system's error.
        err: std::io::Error,
    },
    /// The session was aborted (a signal) before the file was committed.
    #[error("{}: not written: interrupted by a signal (its temporary file was removed)", .0.display())]
    Aborted(PathBuf),
    /// An output is one of the run's inputs.
    #[error("{}: is an input of this run ({}); an input is never written", output.display(), input.display())]
    OutputIsInput {
        /// The output as given.
        output: PathBuf,
        /// The input as given.
        input: PathBuf,
    },
    /// Two outputs of one run are the same file.
    #[error("{} and {}: two outputs of this run are the same file", first.display(), second.display())]
    SameOutput {
        /// The output declared first.
        first: PathBuf,
        /// The output declared second.
        second: PathBuf,
    },
    /// An output path names no file (`.`, `..`, a path ending in `/`).
    #[error("{}: names no file", .0.display())]
    NoFileName(PathBuf),
}

impl WriteError {
    /// True for outputs that collide with an input or with each other, and for an output path
    /// that names no file: the request itself is wrong.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            WriteError::OutputIsInput { .. }
                | WriteError::SameOutput { .. }
                | WriteError::NoFileName(_)
        )
    }
}

/// What every unit of one session shares: the abort flag and the temporaries in existence.
#[derive(Debug)]
struct Shared {
    abort: Arc<AtomicBool>,
    temps: Mutex<BTreeSet<PathBuf>>,
    /// Directories the session created for its outputs, outermost first; removed again (when
    /// still empty) if the run ends having committed nothing.
    made_dirs: Mutex<Vec<PathBuf>>,
    /// Whether any unit was committed.
    committed: AtomicBool,
}

impl Shared {
    fn temps(&self) -> MutexGuard<'_, BTreeSet<PathBuf>> {
        self.temps.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn aborted(&self) -> bool {
        self.abort.load(Ordering::SeqCst)
    }

    /// Removes the directories this session made, innermost first, if nothing was committed
    /// (a directory something else was put in stays: `remove_dir` only removes empty ones).
    fn unmake_dirs(&self) {
        if self.committed.load(Ordering::SeqCst) {
            return;
        }
        let mut dirs = self.made_dirs.lock().unwrap_or_else(|e| e.into_inner());
        for d in std::mem::take(&mut *dirs).iter().rev() {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// What a signal handler holds to stop a session: clone it freely, send it anywhere.
#[derive(Debug, Clone)]
pub struct AbortHandle {
    shared: Arc<Shared>,
}

impl AbortHandle {
    /// The abort flag, for `signal_hook::flag::register`: once set, writes fail at their next
    /// buffer write and nothing more is committed (temporaries are then removed by
    /// the session's clean-up or when their unit is dropped).
    pub fn flag(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.shared.abort)
    }

    /// Aborts the session and removes every temporary it holds, at once (from a signal-handling
    /// thread, before the process exits). Waits for a unit being committed to finish or roll
    /// back. Returns how many temporaries were removed.
    pub fn abort(&self) -> usize {
        let mut temps = self.shared.temps();
        self.shared.abort.store(true, Ordering::SeqCst);
        let n = remove_all(&mut temps);
        self.shared.unmake_dirs();
        n
    }
}

fn remove_all(temps: &mut BTreeSet<PathBuf>) -> usize {
    let mut n = 0;
    for p in std::mem::take(temps) {
        if std::fs::remove_file(&p).is_ok() {
            n += 1;
        }
    }
    n
}

/// A path as the session compares it: resolved, and its file's identity when it exists.
#[derive(Debug)]
struct Known {
    given: PathBuf,
    resolved: PathBuf,
    id: Option<(u64, u64)>,
}

impl Known {
    fn same(&self, other: &Known) -> bool {
        self.resolved == other.resolved || (self.id.is_some() && self.id == other.id)
    }
}

/// `path` made absolute without touching the filesystem (for paths that do not exist).
fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// One command run's outputs (see the [module documentation](self)).
#[derive(Debug)]
pub struct Session {
    overwrite: bool,
    shared: Arc<Shared>,
    inputs: Vec<Known>,
    outputs: Vec<Known>,
}

impl Session {
    /// A session that replaces existing outputs (regular files only) when `overwrite` is true.
    pub fn new(overwrite: bool) -> Session {
        Session {
            overwrite,
            shared: Arc::new(Shared {
                abort: Arc::new(AtomicBool::new(false)),
                temps: Mutex::new(BTreeSet::new()),
                made_dirs: Mutex::new(Vec::new()),
                committed: AtomicBool::new(false),
            }),
            inputs: Vec::new(),
            outputs: Vec::new(),
        }
    }

    /// The handle a signal handler holds to abort this session.
    pub fn abort_handle(&self) -> AbortHandle {
        AbortHandle {
            shared: Arc::clone(&self.shared),
        }
    }

    /// Whether the session was aborted.
    pub fn is_aborted(&self) -> bool {
        self.shared.aborted()
    }

    /// Records an input of the run (a file it reads; one that does not exist is compared by
    /// path only). Fails if an output already declared is this file.
    pub fn input(&mut self, path: &Path) -> Result<(), WriteError> {
        let known = Known {
            given: path.to_path_buf(),
            resolved: std::fs::canonicalize(path).unwrap_or_else(|_| absolute(path)),
            id: std::fs::metadata(path)
                .ok()
                .and_then(|m| nsrm::limits::file_id(&m)),
        };
        if let Some(o) = self.outputs.iter().find(|o| o.same(&known)) {
            return Err(WriteError::OutputIsInput {
                output: o.given.clone(),
                input: known.given,
            });
        }
        self.inputs.push(known);
        Ok(())
    }

    /// Records an output of the run, before any work: creates its parent directories (removed
    /// again if the session ends, or is aborted, having committed nothing), resolves
    /// it (following `..` and symbolic links) and fails if it is an input, another output, an
    /// existing file the session may not replace, or not a regular file.
    pub fn output(&mut self, path: &Path) -> Result<(), WriteError> {
        let name = match path.file_name() {
            Some(n) if !path.as_os_str().as_encoded_bytes().ends_with(b"/") => n,
            _ => return Err(WriteError::NoFileName(path.to_path_buf())),
        };
        let parent = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let io = |err| WriteError::Io {
            path: path.to_path_buf(),
            err,
        };
        self.make_dirs(parent).map_err(io)?;
        let dir = std::fs::canonicalize(parent).map_err(io)?;
        // A symbolic link at the name is compared as the file it points to.
        let resolved = std::fs::canonicalize(path).unwrap_or_else(|_| dir.join(name));
        let known = Known {
            given: path.to_path_buf(),
            resolved,
            id: std::fs::metadata(path)
                .ok()
                .and_then(|m| nsrm::limits::file_id(&m)),
        };
        if let Some(i) = self.inputs.iter().find(|i| i.same(&known)) {
            return Err(WriteError::OutputIsInput {
                output: known.given,
                input: i.given.clone(),
            });
        }
        if let Some(o) = self.outputs.iter().find(|o| o.same(&known)) {
            return Err(WriteError::SameOutput {
                first: o.given.clone(),
                second: known.given,
            });
        }
        self.check_clobber(path)?;
        self.outputs.push(known);
        Ok(())
    }

    /// Creates `dir` and its missing parents, remembering those it made (see [`Drop`]).
    fn make_dirs(&self, dir: &Path) -> std::io::Result<()> {
        let mut missing = Vec::new();
        let mut d = Some(dir);
        while let Some(p) = d.filter(|p| !p.as_os_str().is_empty()) {
            if std::fs::symlink_metadata(p).is_ok() {
                break;
            }
            missing.push(p.to_path_buf());
            d = p.parent();
        }
        std::fs::create_dir_all(dir)?;
        let mut made = self
            .shared
            .made_dirs
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        made.extend(missing.into_iter().rev());
        Ok(())
    }

    /// Fails with [`WriteError::Exists`] if `dest` exists and the session does not overwrite,
    /// and with [`WriteError::NotRegular`] if it exists and is not a regular file.
    pub fn check_clobber(&self, dest: &Path) -> Result<(), WriteError> {
        check_clobber(dest, self.overwrite)
    }

    /// A new unit: outputs written into it are committed together ([`Unit::commit`]).
    pub fn unit(&self) -> Unit {
        Unit {
            shared: Arc::clone(&self.shared),
            overwrite: self.overwrite,
            staged: Vec::new(),
        }
    }

    /// Writes one output on its own: a unit holding just `dest`, committed.
    pub fn write_bytes(&self, dest: &Path, bytes: &[u8]) -> Result<(), WriteError> {
        let mut unit = self.unit();
        unit.write_bytes(dest, bytes)?;
        unit.commit()
    }

    /// Removes every temporary this session still holds (after an abort); returns how many.
    pub fn remove_temporaries(&self) -> usize {
        remove_all(&mut self.shared.temps())
    }

    /// How many temporaries this session holds now.
    #[cfg(test)]
    pub(crate) fn temporaries_held(&self) -> usize {
        self.shared.temps().len()
    }
}

/// A run that ends having committed nothing (refused, failed) leaves no directory it made.
impl Drop for Session {
    fn drop(&mut self) {
        self.shared.unmake_dirs();
    }
}

/// The part of a temporary's name that marks it as this crate's: `.NAME.nsrm-PID-RANDOM.tmp`.
const TEMP_MARK: &str = ".nsrm-";
const TEMP_END: &str = ".tmp";
/// What a temporary's creation fails with once the session is aborted.
const ABORTED: &str = "the session was aborted";

/// Random characters in a temporary's name (ASCII letters and digits, about 95 bits).
const TEMP_RANDOM: usize = 16;

/// Makes something new at a fresh temporary path beside `dest` (same directory, so the final
/// rename is atomic), `.NAME.nsrm-PID-RANDOM.tmp`: `make` creates it and must fail with
/// `AlreadyExists` when the path is taken (`File::create_new`, `hard_link`), and then another
/// name is drawn (the `tempfile` crate's names and retries). Returns what `make` returned and the
/// (absolute) path, which the caller then owns: nothing removes it on drop.
pub(crate) fn make_temp<R>(
    dest: &Path,
    make: impl FnMut(&Path) -> std::io::Result<R>,
) -> std::io::Result<(R, PathBuf)> {
    let mut make = make;
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(dest.file_name().unwrap_or(OsStr::new("out")));
    prefix.push(format!("{TEMP_MARK}{}-", std::process::id()));
    let dir = dest.parent().unwrap_or(Path::new(""));
    let made = tempfile::Builder::new()
        .prefix(&prefix)
        .suffix(TEMP_END)
        .rand_bytes(TEMP_RANDOM)
        .make_in(dir, |p| make(p))?;
    made.keep().map_err(|e| e.error)
}

/// Whether a file name has the form of this crate's temporaries (`.NAME.nsrm-PID-RANDOM.tmp`,
/// [`TEMP_RANDOM`] letters and digits).
pub(crate) fn is_temp_name(name: &OsStr) -> bool {
    let b = name.as_encoded_bytes();
    let Some(rest) = b.strip_suffix(TEMP_END.as_bytes()) else {
        return false;
    };
    let mark = TEMP_MARK.as_bytes();
    let Some(pos) = rest.windows(mark.len()).rposition(|w| w == mark) else {
        return false;
    };
    let tail = &rest[pos + mark.len()..];
    let Some(dash) = tail.iter().position(|&c| c == b'-') else {
        return false;
    };
    let (pid, random) = (&tail[..dash], &tail[dash + 1..]);
    b[0] == b'.'
        && pos > 1
        && !pid.is_empty()
        && pid.iter().all(u8::is_ascii_digit)
        && random.len() == TEMP_RANDOM
        && random.iter().all(u8::is_ascii_alphanumeric)
}

/// The temporaries of this crate's form in `dir` (not recursive), sorted. Left behind by a run
/// that was killed (SIGKILL, power loss); a running `nsrm` elsewhere may also own some, so they
/// are reported, never removed.
pub fn stale_temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_type().map(|t| t.is_file()).unwrap_or(false))
        .map(|e| e.path())
        .filter(|p| p.file_name().is_some_and(is_temp_name))
        .collect();
    found.sort();
    found
}

/// Fails with [`WriteError::Exists`] if `dest` exists and `overwrite` is false, and with
/// [`WriteError::NotRegular`] if it exists and is not a regular file (whatever `overwrite` says).
fn check_clobber(dest: &Path, overwrite: bool) -> Result<(), WriteError> {
    match std::fs::metadata(dest) {
        Ok(meta) if !meta.is_file() => Err(WriteError::NotRegular {
            path: dest.to_path_buf(),
            what: nsrm::limits::file_kind(&meta),
        }),
        Ok(_) if !overwrite => Err(WriteError::Exists(dest.to_path_buf())),
        Ok(_) => Ok(()),
        // A dangling symlink: there is something at the name; never replace it silently.
        Err(_) if !overwrite && std::fs::symlink_metadata(dest).is_ok() => {
            Err(WriteError::Exists(dest.to_path_buf()))
        }
        Err(_) => Ok(()),
    }
}

/// The temporary file an encoder writes into: a [`File`] whose writes fail once the session is
/// aborted, so an interrupted encoder stops at its next buffer write.
#[derive(Debug)]
pub struct OutFile {
    file: File,
    abort: Arc<AtomicBool>,
}

impl OutFile {
    fn check(&self) -> std::io::Result<()> {
        if self.abort.load(Ordering::Relaxed) {
            Err(std::io::Error::other("interrupted by a signal"))
        } else {
            Ok(())
        }
    }
}

impl Write for OutFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.check()?;
        self.file.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.check()?;
        self.file.write_all(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl Seek for OutFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.file.seek(pos)
    }
}

/// A finished temporary waiting for its unit's commit.
#[derive(Debug)]
struct Staged {
    tmp: PathBuf,
    dest: PathBuf,
}

/// Outputs that belong together: each written into a temporary, all moved into place by
/// [`commit`](Self::commit). Dropping a unit without committing removes its temporaries.
#[derive(Debug)]
pub struct Unit {
    shared: Arc<Shared>,
    overwrite: bool,
    staged: Vec<Staged>,
}

impl Unit {
    /// Fails if `dest` exists and may not be replaced (see [`Session::check_clobber`]).
    pub fn check_clobber(&self, dest: &Path) -> Result<(), WriteError> {
        check_clobber(dest, self.overwrite)
    }

    /// Whether no file is staged.
    #[cfg(test)]
    pub(crate) fn is_empty(&self) -> bool {
        self.staged.is_empty()
    }

    /// Creates a fresh temporary beside `dest` (never opening an existing file), registered
    /// with the session; refused once the session is aborted.
    fn create_temp(&self, dest: &Path) -> Result<(OutFile, PathBuf), WriteError> {
        let made = make_temp(dest, |tmp| {
            // Created and registered under the lock, so an abort sees every temporary.
            let mut temps = self.shared.temps();
            if self.shared.aborted() {
                return Err(std::io::Error::other(ABORTED));
            }
            let file = File::create_new(tmp)?;
            temps.insert(tmp.to_path_buf());
            Ok(file)
        });
        match made {
            Ok((file, tmp)) => {
                let f = OutFile {
                    file,
                    abort: Arc::clone(&self.shared.abort),
                };
                Ok((f, tmp))
            }
            Err(_) if self.shared.aborted() => Err(WriteError::Aborted(dest.to_path_buf())),
            Err(err) => Err(WriteError::Io {
                path: dest.to_path_buf(),
                err,
            }),
        }
    }

    fn forget(&self, tmp: &Path) {
        let _ = std::fs::remove_file(tmp);
        self.shared.temps().remove(tmp);
    }

    /// Writes `dest`'s temporary through an encoder: `write` fills a buffered writer on a fresh
    /// temporary beside `dest`, which is then flushed, synced and staged in this unit. On any
    /// error the temporary is removed and `dest` is untouched.
    pub fn write_with<E: From<WriteError>>(
        &mut self,
        dest: &Path,
        write: impl FnOnce(&mut BufWriter<OutFile>) -> Result<(), E>,
    ) -> Result<(), E> {
        self.check_clobber(dest)?;
        let (file, tmp) = self.create_temp(dest)?;
        let io = |err| WriteError::Io {
            path: dest.to_path_buf(),
            err,
        };
        let mut w = BufWriter::new(file);
        let done = write(&mut w).and_then(|()| {
            w.flush().map_err(io)?;
            let file = w.into_inner().map_err(|e| io(e.into_error()))?;
            file.file.sync_all().map_err(io)?;
            if self.shared.aborted() {
                return Err(E::from(WriteError::Aborted(dest.to_path_buf())));
            }
            Ok(())
        });
        match done {
            Ok(()) => {
                self.staged.push(Staged {
                    tmp,
                    dest: dest.to_path_buf(),
                });
                Ok(())
            }
            Err(e) => {
                self.forget(&tmp);
                Err(e)
            }
        }
    }

    /// Stages `bytes` for `dest`: writes them to a fresh temporary beside it (flushed and
    /// synced), committed with the unit; on any error the temporary is removed and `dest` is
    /// untouched.
    pub fn write_bytes(&mut self, dest: &Path, bytes: &[u8]) -> Result<(), WriteError> {
        self.write_with(dest, |w| {
            w.write_all(bytes).map_err(|err| WriteError::Io {
                path: dest.to_path_buf(),
                err,
            })
        })
    }

    /// Moves every staged file into place, together: every destination is checked first, then
    /// each is placed; if one fails, the ones already placed are taken back and a file that
    /// `overwrite` replaced is put back (kept aside as a hard link meanwhile; on a filesystem
    /// without hard links it is not restored). Without `overwrite` each final step is a hard
    /// link, which fails if the destination appeared meanwhile. The session's lock is held
    /// throughout, so an abort waits for the unit to be placed or rolled back.
    pub fn commit(mut self) -> Result<(), WriteError> {
        let staged = std::mem::take(&mut self.staged);
        let shared = Arc::clone(&self.shared);
        let mut temps = shared.temps();
        let drop_temps = |temps: &mut BTreeSet<PathBuf>, staged: &[Staged]| {
            for s in staged {
                let _ = std::fs::remove_file(&s.tmp);
                temps.remove(&s.tmp);
            }
        };
        if shared.aborted() {
            drop_temps(&mut temps, &staged);
            let first = staged.first().map(|s| s.dest.clone()).unwrap_or_default();
            return Err(WriteError::Aborted(first));
        }
        if let Err(e) = staged
            .iter()
            .try_for_each(|s| check_clobber(&s.dest, self.overwrite))
        {
            drop_temps(&mut temps, &staged);
            return Err(e);
        }
        // (destination, the file it replaced kept aside)
        let mut placed: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
        for (k, s) in staged.iter().enumerate() {
            let backup = if self.overwrite && std::fs::symlink_metadata(&s.dest).is_ok() {
                make_temp(&s.dest, |b| std::fs::hard_link(&s.dest, b))
                    .ok()
                    .map(|((), b)| {
                        temps.insert(b.clone());
                        b
                    })
            } else {
                None
            };
            if let Err(e) = place(&s.tmp, &s.dest, self.overwrite) {
                if let Some(b) = &backup {
                    let _ = std::fs::remove_file(b);
                    temps.remove(b);
                }
                // Take back what this unit placed, newest first.
                for (p, backup) in placed.iter().rev() {
                    match backup {
                        Some(b) => {
                            let _ = std::fs::rename(b, p);
                            temps.remove(b);
                        }
                        None => {
                            let _ = std::fs::remove_file(p);
                        }
                    }
                }
                drop_temps(&mut temps, &staged[k..]);
                drop_temps(&mut temps, &staged[..k]);
                return Err(e);
            }
            // Placed: the temporary is gone (renamed) or a second link (removed now).
            let _ = std::fs::remove_file(&s.tmp);
            temps.remove(&s.tmp);
            placed.push((s.dest.clone(), backup));
        }
        for (_, b) in placed {
            if let Some(b) = b {
                let _ = std::fs::remove_file(&b);
                temps.remove(&b);
            }
        }
        if !staged.is_empty() {
            shared.committed.store(true, Ordering::SeqCst);
        }
        Ok(())
    }
}

impl Drop for Unit {
    fn drop(&mut self) {
        for s in std::mem::take(&mut self.staged) {
            self.forget(&s.tmp);
        }
    }
}

/// Moves a finished temporary onto `dest`: a hard link without `overwrite` (fails if `dest`
/// appeared meanwhile), else a rename after checking `dest` is (still) a regular file or absent.
fn place(tmp: &Path, dest: &Path, overwrite: bool) -> Result<(), WriteError> {
    check_clobber(dest, overwrite)?;
    let result = if overwrite {
        std::fs::rename(tmp, dest)
    } else {
        match std::fs::hard_link(tmp, dest) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                return Err(WriteError::Exists(dest.to_path_buf()));
            }
            // Filesystems without hard links: check, then rename.
            Err(_) if std::fs::symlink_metadata(dest).is_err() => std::fs::rename(tmp, dest),
            Err(e) => Err(e),
        }
    };
    result.map_err(|err| WriteError::Io {
        path: dest.to_path_buf(),
        err,
    })
}

/// An output's refusal or failure as the library's frame error, so an encoder written for the
/// library (`Result<(), IoError>`) runs inside [`Unit::write_with`].
impl From<WriteError> for nsrm_io::IoError {
    fn from(e: WriteError) -> Self {
        nsrm_io::IoError::Output {
            usage: e.is_usage(),
            err: Box::new(e),
        }
    }
}

/// A batch's frames through the session: each frame's files staged in one [`Unit`] and committed
/// together; a signal's abort reported as such.
impl nsrm_io::batch::FrameSink for Session {
    fn write_together(
        &self,
        files: Vec<(&Path, nsrm_io::batch::Encoder<'_>)>,
    ) -> Result<(), nsrm_io::IoError> {
        let mut unit = self.unit();
        for (dest, encode) in files {
            unit.write_with(dest, |w| encode(w))?;
        }
        Ok(unit.commit()?)
    }

    fn is_aborted(&self) -> bool {
        Session::is_aborted(self)
    }
}

#[cfg(test)]
mod tests;
