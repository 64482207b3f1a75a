//! Batches on farm engines: per-shard manifests, their verification, path mapping between the
//! submitting machine and the workers, and job descriptions in the engines' own formats.
//!
//! A batch of `N` shards is split as `--shard` says. Each shard, when it has
//! run, writes a manifest beside the outputs (atomically): its inputs, their
//! outputs with sizes and SHA-256 hashes, the model's hash, the nsrm version, timings and
//! failures. `nsrm farm verify` reads every manifest of an output directory and checks the batch
//! is whole: every shard present, each input with exactly one complete output from one model, the
//! hashes matching the files, and no temporary left.
//!
//! The job descriptions (`jobs`) are built from the command line a worker runs, which the
//! caller supplies: this module knows the engines' formats, not the binary's flags.
//!
//! Everything here is private to the command line: the `nsrm farm` commands and `nsrm apply
//! --shard` are its only users.

pub(crate) mod jobs;
pub(crate) mod manifest;
pub(crate) mod pathmap;
pub(crate) mod resources;
pub(crate) mod tasklog;
pub(crate) mod verify;
pub(crate) mod yaml;

use std::path::{Path, PathBuf};

/// What can go wrong reading or writing a batch's farm records.
#[derive(Debug, thiserror::Error)]
pub(crate) enum FarmError {
    /// A file cannot be read or written.
    #[error("{}: {err}", path.display())]
    Io { path: PathBuf, err: std::io::Error },
    /// A manifest or rules file is not what it should be.
    #[error("{}: {why}", path.display())]
    Format { path: PathBuf, why: String },
    /// A request that cannot be carried out as given (a malformed mapping rule, a shard count of
    /// zero, a path a job format cannot hold).
    #[error("{0}")]
    Usage(String),
    /// Writing the manifest failed.
    #[error(transparent)]
    Write(#[from] nsrm_output::WriteError),
}

impl FarmError {
    /// True for requests that cannot be carried out as given.
    pub(crate) fn is_usage(&self) -> bool {
        matches!(self, FarmError::Usage(_))
    }
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> FarmError + '_ {
    move |err| FarmError::Io {
        path: path.to_path_buf(),
        err,
    }
}

/// The most shards a batch has (Kubernetes' limit on an Indexed Job's completions; Slurm's
/// array size is configured lower by default). A larger count, from a flag, a manifest or a
/// manifest's file name, is refused before anything is sized by it.
pub(crate) const MAX_SHARDS: usize = 100_000;

/// The most bytes of a manifest or rules file read (a batch of a million frames fits).
pub(crate) const MAX_RECORD_BYTES: u64 = 1 << 30;

/// Reads a whole small file, refusing one larger than `limit` bytes before allocating.
pub(crate) fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>, FarmError> {
    use std::io::Read;
    let f = std::fs::File::open(path).map_err(io_err(path))?;
    let len = f.metadata().map_err(io_err(path))?.len();
    if len > limit {
        return Err(FarmError::Format {
            path: path.to_path_buf(),
            why: format!("{len} bytes, more than the {limit} read at most"),
        });
    }
    let mut out = Vec::with_capacity(len as usize);
    f.take(limit + 1)
        .read_to_end(&mut out)
        .map_err(io_err(path))?;
    if out.len() as u64 > limit {
        return Err(FarmError::Format {
            path: path.to_path_buf(),
            why: format!("more than the {limit} bytes read at most"),
        });
    }
    Ok(out)
}

/// A file's size and SHA-256 (lowercase hex), read in 1 MiB blocks.
pub(crate) fn sha256_file(path: &Path) -> Result<(u64, String), FarmError> {
    use sha2::{Digest, Sha256};
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(io_err(path))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut size = 0u64;
    loop {
        let n = f.read(&mut buf).map_err(io_err(path))?;
        if n == 0 {
            break;
        }
        size += n as u64;
        h.update(&buf[..n]);
    }
    Ok((size, hex(&h.finalize())))
}

/// SHA-256 (lowercase hex) of bytes.
pub(crate) fn sha256_bytes(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    hex(&Sha256::digest(bytes))
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}
