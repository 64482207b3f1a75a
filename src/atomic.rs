//! Writing outputs without losing anything: a temporary file in the destination's directory,
//! renamed into place only when complete, and no replacement of an existing file unless asked.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Errors from writing an output file.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error("{0}: already exists (pass --overwrite to replace it)")]
    Exists(PathBuf),
    #[error("{path}: cannot write: {err}")]
    Io {
        path: PathBuf,
        #[source]
        err: std::io::Error,
    },
}

/// A temporary path beside `dest` (same directory, so the final rename is atomic), unique per
/// process and call: `.NAME.PID-N.tmp`.
pub fn temp_path_for(dest: &Path) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = dest
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = format!(".{name}.{}-{n}.tmp", std::process::id());
    match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.join(tmp),
        _ => PathBuf::from(tmp),
    }
}

/// Fails with [`WriteError::Exists`] if `dest` exists and `overwrite` is false.
pub fn check_clobber(dest: &Path, overwrite: bool) -> Result<(), WriteError> {
    if !overwrite && dest.exists() {
        return Err(WriteError::Exists(dest.to_path_buf()));
    }
    Ok(())
}

/// Moves a finished temporary file onto `dest`. Without `overwrite` the final step is a hard
/// link, which fails if `dest` appeared meanwhile (no race with another writer); with it, a rename.
/// The temporary file is removed on failure.
pub fn commit(tmp: &Path, dest: &Path, overwrite: bool) -> Result<(), WriteError> {
    let result = if overwrite {
        std::fs::rename(tmp, dest)
    } else {
        match std::fs::hard_link(tmp, dest) {
            Ok(()) => std::fs::remove_file(tmp),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let _ = std::fs::remove_file(tmp);
                return Err(WriteError::Exists(dest.to_path_buf()));
            }
            // Filesystems without hard links: check, then rename.
            Err(_) if !dest.exists() => std::fs::rename(tmp, dest),
            Err(e) => Err(e),
        }
    };
    result.map_err(|err| {
        let _ = std::fs::remove_file(tmp);
        WriteError::Io {
            path: dest.to_path_buf(),
            err,
        }
    })
}

/// Writes `dest` atomically through an encoder: `write` fills a buffered writer on a fresh
/// temporary file beside `dest`; the file is then flushed, synced and moved into place
/// ([`commit`]). On any error the temporary file is removed and `dest` is untouched.
pub fn write_with<E: From<WriteError>>(
    dest: &Path,
    overwrite: bool,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), E>,
) -> Result<(), E> {
    check_clobber(dest, overwrite)?;
    let tmp = temp_path_for(dest);
    let io = |err| {
        E::from(WriteError::Io {
            path: dest.to_path_buf(),
            err,
        })
    };
    let result = (|| -> Result<(), E> {
        let mut w = BufWriter::new(File::create_new(&tmp).map_err(io)?);
        write(&mut w)?;
        w.flush().map_err(io)?;
        let file = w.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    Ok(commit(&tmp, dest, overwrite)?)
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

    #[test]
    fn refuses_to_clobber_and_leaves_no_temp() {
        let dir = std::env::temp_dir().join(format!("nsrm-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("a.json");
        let _ = std::fs::remove_file(&f);
        write_atomic(&f, b"one", false).unwrap();
        let e = write_atomic(&f, b"two", false).unwrap_err();
        assert!(matches!(e, WriteError::Exists(_)));
        assert_eq!(std::fs::read(&f).unwrap(), b"one");
        write_atomic(&f, b"two", true).unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        let leftovers = std::fs::read_dir(&dir)
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .ends_with(".tmp")
            })
            .count();
        assert_eq!(leftovers, 0);
        let e = write_atomic(&dir.join("no/such/dir/x"), b"x", false).unwrap_err();
        assert!(e.to_string().contains("cannot write"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
