//! Writing outputs without losing anything: a temporary file in the destination's directory,
//! renamed into place only when complete, and no replacement of an existing file unless asked.
//!
//! * Temporary names are unguessable: `.NAME.nsrm-PID-RANDOM.tmp`, with 64 random bits from the
//!   operating system, created with `O_EXCL` (`File::create_new`). Two processes with the same
//!   PID (PID 1 in two containers sharing a volume) never meet; a name that exists anyway is never
//!   touched, another one is drawn.
//! * Only temporaries this process created are ever removed. Each one is registered while it
//!   exists, so an interrupted run can remove exactly its own ([`remove_temporaries`]).
//! * Nothing but a regular file is ever replaced, even with `overwrite`: a FIFO, a device, a
//!   socket or a directory at the destination is an error ([`WriteError::NotRegular`]).
//! * Outputs that belong together are staged first and committed together ([`commit_all`]): both
//!   appear, or neither. Writers deeper down (the EXR and TIFF encoders) stage instead of
//!   committing while their caller collects ([`collect_staged`]).
//! * After [`abort_flag`] is set (by a signal handler), every write in progress fails at its next
//!   buffer flush, its temporary is removed, and nothing more is committed ([`WriteError::Aborted`]).

use std::cell::RefCell;
use std::collections::BTreeSet;
use std::ffi::OsStr;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::io::{Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// Errors from writing an output file.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error("{}: already exists (not replaced)", .0.display())]
    Exists(PathBuf),
    #[error("{}: not a regular file (it is {what}); only regular files are ever replaced", path.display())]
    NotRegular { path: PathBuf, what: &'static str },
    #[error("{}: cannot write: {err}", path.display())]
    Io { path: PathBuf, err: std::io::Error },
    #[error("{}: not written: interrupted by a signal (its temporary file was removed)", .0.display())]
    Aborted(PathBuf),
}

/// Set (by a signal handler: `signal_hook::flag::register(SIGTERM, abort_flag())`) to abort
/// every write: a file being written fails at its next buffer flush and its temporary is
/// removed; nothing is committed afterwards. Never cleared.
pub fn abort_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    Arc::clone(FLAG.get_or_init(|| Arc::new(AtomicBool::new(false))))
}

/// Whether writes are being aborted (see [`abort_flag`]).
pub fn writes_aborted() -> bool {
    abort_flag().load(Ordering::SeqCst)
}

/// The temporary file an encoder writes into: a [`File`] whose writes fail once
/// [`abort_flag`] is set, so an interrupted encoder stops at its next flush.
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

thread_local! {
    /// Set by [`collect_staged`]: finished files are kept here instead of being committed.
    static COLLECTING: RefCell<Option<Vec<Staged>>> = const { RefCell::new(None) };
}

/// Runs `f` with every file that [`write_with`] (and so [`write_atomic`] and the frame
/// writers) finishes on this thread staged instead of committed, and returns them, for
/// [`commit_all`]. On error the staged files are dropped (their temporaries removed).
pub fn collect_staged<R, E>(f: impl FnOnce() -> Result<R, E>) -> Result<(R, Vec<Staged>), E> {
    let outer = COLLECTING.with(|c| c.borrow_mut().replace(Vec::new()));
    let r = f();
    let staged = COLLECTING.with(|c| std::mem::replace(&mut *c.borrow_mut(), outer));
    let staged = staged.unwrap_or_default();
    r.map(|v| (v, staged))
}

/// The part of a temporary's name that marks it as this crate's: `.NAME.nsrm-PID-RANDOM.tmp`.
const TEMP_MARK: &str = ".nsrm-";
const TEMP_END: &str = ".tmp";

/// Temporaries created by this process and not yet moved into place or removed.
static TEMPS: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());

fn temps() -> std::sync::MutexGuard<'static, BTreeSet<PathBuf>> {
    TEMPS.lock().unwrap_or_else(|e| e.into_inner())
}

/// 64 unpredictable bits: from the operating system, else (no entropy source) from std's
/// randomly keyed hasher over the time and a counter.
fn random_u64() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    if let Ok(v) = getrandom::u64() {
        return v;
    }
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    if let Ok(t) = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        h.write_u128(t.as_nanos());
    }
    h.finish()
}

/// A fresh temporary path beside `dest` (same directory, so the final rename is atomic):
/// `.NAME.nsrm-PID-RANDOM.tmp`. Nothing is created.
pub fn temp_path_for(dest: &Path) -> PathBuf {
    let mut name = std::ffi::OsString::from(".");
    name.push(dest.file_name().unwrap_or(OsStr::new("out")));
    name.push(format!(
        "{TEMP_MARK}{}-{:016x}{TEMP_END}",
        std::process::id(),
        random_u64()
    ));
    match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.join(name),
        _ => PathBuf::from(name),
    }
}

/// Whether a file name has the form of this crate's temporaries (`.NAME.nsrm-PID-HEX16.tmp`).
pub fn is_temp_name(name: &OsStr) -> bool {
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
    let (pid, hex) = (&tail[..dash], &tail[dash + 1..]);
    b[0] == b'.'
        && pos > 1
        && !pid.is_empty()
        && pid.iter().all(u8::is_ascii_digit)
        && hex.len() == 16
        && hex.iter().all(u8::is_ascii_hexdigit)
}

/// The temporaries of this crate's form in `dir` (not recursive), sorted. Left behind by a run
/// that was killed (SIGKILL, power loss); a running `nsrm` elsewhere may also own some, so they
/// are reported, and removed only when asked.
pub fn stale_temporaries(dir: &Path) -> Vec<PathBuf> {
    let own = temps();
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_type().map(|t| t.is_file()).unwrap_or(false))
        .map(|e| e.path())
        .filter(|p| p.file_name().is_some_and(is_temp_name) && !own.contains(p))
        .collect();
    found.sort();
    found
}

/// Removes every temporary this process created and still holds (after an interrupt); returns
/// how many were removed. Nothing else is touched.
pub fn remove_temporaries() -> usize {
    let mut set = temps();
    let mut n = 0;
    for p in std::mem::take(&mut *set) {
        if std::fs::remove_file(&p).is_ok() {
            n += 1;
        }
    }
    n
}

/// How many temporaries this process holds now.
pub fn temporaries_held() -> usize {
    temps().len()
}

/// Fails with [`WriteError::Exists`] if `dest` exists and `overwrite` is false, and with
/// [`WriteError::NotRegular`] if it exists and is not a regular file (whatever `overwrite` says).
pub fn check_clobber(dest: &Path, overwrite: bool) -> Result<(), WriteError> {
    match std::fs::metadata(dest) {
        Ok(meta) if !meta.is_file() => Err(WriteError::NotRegular {
            path: dest.to_path_buf(),
            what: crate::limits::file_kind(&meta),
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

/// A finished temporary file waiting to be moved onto its destination. Dropping it without
/// [`commit`](Self::commit) removes the temporary (which this process created).
#[derive(Debug)]
pub struct Staged {
    tmp: PathBuf,
    dest: PathBuf,
    overwrite: bool,
    done: bool,
}

impl Staged {
    /// Creates a fresh temporary beside `dest` (never opening an existing file).
    fn create(dest: &Path, overwrite: bool) -> Result<(OutFile, Staged), WriteError> {
        let mut last = None;
        for _ in 0..16 {
            let tmp = temp_path_for(dest);
            match File::create_new(&tmp) {
                Ok(f) => {
                    temps().insert(tmp.clone());
                    let f = OutFile {
                        file: f,
                        abort: abort_flag(),
                    };
                    return Ok((
                        f,
                        Staged {
                            tmp,
                            dest: dest.to_path_buf(),
                            overwrite,
                            done: false,
                        },
                    ));
                }
                // Someone else's file: leave it alone, draw another name.
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
                Err(err) => {
                    return Err(WriteError::Io {
                        path: dest.to_path_buf(),
                        err,
                    })
                }
            }
        }
        Err(WriteError::Io {
            path: dest.to_path_buf(),
            err: last.unwrap_or_else(|| std::io::Error::other("no free temporary name")),
        })
    }

    /// The destination.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// The temporary file.
    pub fn temp(&self) -> &Path {
        &self.tmp
    }

    /// Moves the temporary onto the destination. Without `overwrite` the final step is a hard
    /// link, which fails if the destination appeared meanwhile (no race with another writer);
    /// with it, a rename, after checking the destination is (still) a regular file or absent.
    pub fn commit(mut self) -> Result<(), WriteError> {
        if writes_aborted() {
            self.discard();
            return Err(WriteError::Aborted(self.dest.clone()));
        }
        let r = commit_path(&self.tmp, &self.dest, self.overwrite);
        self.discard();
        r
    }

    fn discard(&mut self) {
        if !self.done {
            self.done = true;
            // Gone already after a successful rename; otherwise it is ours to remove.
            let _ = std::fs::remove_file(&self.tmp);
            temps().remove(&self.tmp);
        }
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        self.discard();
    }
}

fn commit_path(tmp: &Path, dest: &Path, overwrite: bool) -> Result<(), WriteError> {
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

/// Moves a finished temporary file onto `dest` (see [`Staged::commit`]); the temporary is
/// removed in every case. `tmp` must be a file this process created.
pub fn commit(tmp: &Path, dest: &Path, overwrite: bool) -> Result<(), WriteError> {
    let r = if writes_aborted() {
        Err(WriteError::Aborted(dest.to_path_buf()))
    } else {
        commit_path(tmp, dest, overwrite)
    };
    let _ = std::fs::remove_file(tmp);
    temps().remove(tmp);
    r
}

/// Commits files that belong together: every destination is checked first, then each is moved
/// into place; if one fails, the ones this call already placed are taken back, so they appear
/// together or not at all. A file they replaced (with `overwrite`) is kept aside as a hard link
/// until all are placed and put back on failure (where the filesystem has no hard links it is
/// not restored).
pub fn commit_all(staged: Vec<Staged>) -> Result<(), WriteError> {
    for s in &staged {
        check_clobber(&s.dest, s.overwrite)?;
    }
    if writes_aborted() {
        return Err(WriteError::Aborted(
            staged.first().map(|s| s.dest.clone()).unwrap_or_default(),
        ));
    }
    // (destination, the file it replaced kept aside)
    let mut placed: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
    let restore = |placed: &[(PathBuf, Option<PathBuf>)]| {
        for (p, backup) in placed.iter().rev() {
            match backup {
                Some(b) => {
                    let _ = std::fs::rename(b, p);
                    temps().remove(b);
                }
                None => {
                    let _ = std::fs::remove_file(p);
                }
            }
        }
    };
    for s in staged {
        let dest = s.dest.clone();
        let backup = if s.overwrite && std::fs::symlink_metadata(&dest).is_ok() {
            let b = temp_path_for(&dest);
            std::fs::hard_link(&dest, &b).ok().map(|()| {
                temps().insert(b.clone());
                b
            })
        } else {
            None
        };
        if let Err(e) = s.commit() {
            if let Some(b) = &backup {
                let _ = std::fs::remove_file(b);
                temps().remove(b);
            }
            restore(&placed);
            return Err(e);
        }
        placed.push((dest, backup));
    }
    for (_, b) in placed {
        if let Some(b) = b {
            let _ = std::fs::remove_file(&b);
            temps().remove(&b);
        }
    }
    Ok(())
}

/// Writes a temporary for `dest` through an encoder and returns it staged (flushed and synced),
/// not yet in place. On any error the temporary is removed and `dest` is untouched.
pub fn stage_with<E: From<WriteError>>(
    dest: &Path,
    overwrite: bool,
    write: impl FnOnce(&mut BufWriter<OutFile>) -> Result<(), E>,
) -> Result<Staged, E> {
    check_clobber(dest, overwrite)?;
    let (file, staged) = Staged::create(dest, overwrite)?;
    let io = |err| {
        E::from(WriteError::Io {
            path: dest.to_path_buf(),
            err,
        })
    };
    let mut w = BufWriter::new(file);
    write(&mut w)?;
    w.flush().map_err(io)?;
    let file = w.into_inner().map_err(|e| io(e.into_error()))?;
    file.file.sync_all().map_err(io)?;
    if writes_aborted() {
        return Err(E::from(WriteError::Aborted(dest.to_path_buf())));
    }
    Ok(staged)
}

/// Writes `dest` atomically through an encoder: `write` fills a buffered writer on a fresh
/// temporary file beside `dest`; the file is then flushed, synced and moved into place
/// ([`Staged::commit`]) — or, inside [`collect_staged`], kept staged for the caller. On any
/// error the temporary file is removed and `dest` is untouched.
pub fn write_with<E: From<WriteError>>(
    dest: &Path,
    overwrite: bool,
    write: impl FnOnce(&mut BufWriter<OutFile>) -> Result<(), E>,
) -> Result<(), E> {
    let staged = stage_with(dest, overwrite, write)?;
    let staged = COLLECTING.with(|c| match c.borrow_mut().as_mut() {
        Some(list) => {
            list.push(staged);
            None
        }
        None => Some(staged),
    });
    match staged {
        Some(s) => Ok(s.commit()?),
        None => Ok(()),
    }
}

/// Stages `bytes` for `dest` (see [`stage_with`]).
pub fn stage_bytes(dest: &Path, bytes: &[u8], overwrite: bool) -> Result<Staged, WriteError> {
    stage_with(dest, overwrite, |w| {
        w.write_all(bytes).map_err(|err| WriteError::Io {
            path: dest.to_path_buf(),
            err,
        })
    })
}

/// Writes `bytes` to `dest` atomically (temp file + fsync + rename).
pub fn write_atomic(dest: &Path, bytes: &[u8], overwrite: bool) -> Result<(), WriteError> {
    write_with(dest, overwrite, |w| {
        w.write_all(bytes).map_err(|err| WriteError::Io {
            path: dest.to_path_buf(),
            err,
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leftovers(dir: &Path) -> usize {
        std::fs::read_dir(dir)
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .ends_with(".tmp")
            })
            .count()
    }

    #[test]
    fn refuses_to_clobber_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let dir = dir.path();
        let f = dir.join("a.json");
        write_atomic(&f, b"one", false).unwrap();
        let e = write_atomic(&f, b"two", false).unwrap_err();
        assert!(matches!(e, WriteError::Exists(_)));
        assert_eq!(std::fs::read(&f).unwrap(), b"one");
        write_atomic(&f, b"two", true).unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        assert_eq!(leftovers(dir), 0);
        let e = write_atomic(&dir.join("no/such/dir/x"), b"x", false).unwrap_err();
        assert!(e.to_string().contains("cannot write"));
        // A directory is never replaced, even with overwrite.
        std::fs::create_dir(dir.join("d")).unwrap();
        let e = write_atomic(&dir.join("d"), b"x", true).unwrap_err();
        assert!(
            e.to_string()
                .contains("not a regular file (it is a directory)"),
            "{e}"
        );
    }

    #[test]
    fn temp_names_are_unique_and_recognised() {
        let a = temp_path_for(Path::new("out/x.exr"));
        let b = temp_path_for(Path::new("out/x.exr"));
        assert_ne!(a, b);
        assert!(is_temp_name(a.file_name().unwrap()), "{a:?}");
        assert!(a.to_string_lossy().starts_with("out/.x.exr.nsrm-"), "{a:?}");
        for bad in [
            "x.tmp",
            ".x.nsrm-1-abc.tmp",
            ".x.nsrm--0123456789abcdef.tmp",
            ".nsrm-1-0123456789abcdef.tmp",
        ] {
            assert!(!is_temp_name(OsStr::new(bad)), "{bad}");
        }
        assert!(is_temp_name(OsStr::new(
            ".x.exr.nsrm-1-0123456789abcdef.tmp"
        )));
    }

    #[test]
    fn a_dropped_stage_removes_only_its_own_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("x.bin");
        // Someone else's file that looks like a temporary is never touched.
        let other = dir.path().join(".x.bin.nsrm-1-0123456789abcdef.tmp");
        std::fs::write(&other, b"theirs").unwrap();
        let s = stage_bytes(&dest, b"mine", false).unwrap();
        assert!(s.temp().exists());
        assert_eq!(stale_temporaries(dir.path()), vec![other.clone()]);
        drop(s);
        assert!(!dest.exists());
        assert_eq!(std::fs::read(&other).unwrap(), b"theirs");
        assert_eq!(leftovers(dir.path()), 1);
    }

    #[test]
    fn a_failing_encoder_leaves_nothing_behind() {
        // A write failure (disk full, an encoder error) half-way through: simulated by the
        // encoder, since a full filesystem cannot be made in CI.
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("x.exr");
        let r: Result<(), WriteError> = write_with(&dest, false, |w| {
            w.write_all(&[0u8; 100_000]).unwrap();
            Err(WriteError::Io {
                path: dest.clone(),
                err: std::io::Error::new(std::io::ErrorKind::StorageFull, "no space left"),
            })
        });
        assert!(r.unwrap_err().to_string().contains("no space left"));
        assert!(!dest.exists());
        assert_eq!(leftovers(dir.path()), 0);
    }

    #[test]
    fn commit_all_places_both_or_neither() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a");
        let b = dir.path().join("b");
        std::fs::write(&b, b"old").unwrap();
        let sa = stage_bytes(&a, b"1", false).unwrap();
        let sb = stage_bytes(&dir.path().join("c"), b"2", false).unwrap();
        // b appears before the commit: c's destination is fine but refuse a clash for a.
        std::fs::write(&a, b"raced").unwrap();
        assert!(commit_all(vec![sa, sb]).is_err());
        assert!(!dir.path().join("c").exists());
        assert_eq!(std::fs::read(&a).unwrap(), b"raced");
        assert_eq!(leftovers(dir.path()), 0);
        let sa = stage_bytes(&dir.path().join("d"), b"1", false).unwrap();
        let sb = stage_bytes(&dir.path().join("e"), b"2", false).unwrap();
        commit_all(vec![sa, sb]).unwrap();
        assert!(dir.path().join("d").exists() && dir.path().join("e").exists());
    }
}
