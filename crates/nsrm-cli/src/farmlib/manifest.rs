//! The record a shard leaves beside its outputs.

use super::{read_bounded, FarmError, MAX_RECORD_BYTES};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` of a shard manifest this version writes and reads.
pub(crate) const FORMAT: &str = "nsrm-farm-shard/1";

/// How a shard came by one of its outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum How {
    /// Written by this run.
    Converted,
    /// Finished by an earlier run of the shard: its size and hash matched that run's manifest.
    Kept,
    /// Found complete (read in full) without a record, e.g. after a run killed before it wrote
    /// its manifest: kept, not redone.
    Adopted,
    /// Found broken or from another model or settings, and written again by this run.
    Replaced,
}

/// One output of the shard.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Entry {
    /// The input, as the worker named it.
    pub input: String,
    /// The output's file name in the output directory.
    pub output: String,
    pub bytes: u64,
    pub sha256: String,
    /// The preview's file name and hash, when previews were asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preview: Option<Preview>,
    pub how: How,
}

/// A preview written with an output.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Preview {
    /// As the worker named it.
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
}

/// An input the shard could not convert.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Failure {
    pub input: String,
    pub output: String,
    pub why: String,
}

/// Seconds spent by the run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct Timings {
    /// Start, in seconds since the Unix epoch.
    pub started_unix: f64,
    /// Checking what earlier runs left (hashes, full reads).
    pub check_s: f64,
    /// Converting.
    pub convert_s: f64,
    /// Hashing what was converted.
    pub hash_s: f64,
    pub total_s: f64,
}

/// What the whole batch is: its size and the SHA-256 of its outputs' names in batch order (the
/// same on every worker, whatever their mount points).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Batch {
    pub inputs: usize,
    pub outputs_sha256: String,
}

impl Batch {
    /// The identity of a batch whose outputs are named `names`, in batch order.
    pub(crate) fn of<S: AsRef<str>>(names: &[S]) -> Batch {
        let mut joined = String::new();
        for n in names {
            joined.push_str(n.as_ref());
            joined.push('\n');
        }
        Batch {
            inputs: names.len(),
            outputs_sha256: super::sha256_bytes(joined.as_bytes()),
        }
    }
}

/// The model a shard applied.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct ModelRecord {
    /// As the worker named it.
    pub path: String,
    pub sha256: String,
}

/// One shard's record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct ShardManifest {
    /// [`FORMAT`].
    pub format: String,
    pub nsrm_version: String,
    /// 1-based.
    pub shard: usize,
    pub shards: usize,
    pub batch: Batch,
    pub model: ModelRecord,
    /// The conversion settings besides paths (the same for every shard of a batch).
    pub settings: Vec<String>,
    /// The shard's outputs, in batch order.
    pub outputs: Vec<Entry>,
    pub failures: Vec<Failure>,
    /// nsrm temporaries of this shard's outputs found (left by a killed run) and removed.
    pub stale_temporaries_removed: Vec<String>,
    pub timings: Timings,
}

/// The manifest's file name for shard `k` of `n`: `nsrm-farm.shard-0002-of-0008.json`.
pub(crate) fn file_name(k: usize, n: usize) -> String {
    format!("nsrm-farm.shard-{k:04}-of-{n:04}.json")
}

/// Parses a manifest's file name back to `(k, n)`.
pub(crate) fn parse_file_name(name: &str) -> Option<(usize, usize)> {
    let rest = name
        .strip_prefix("nsrm-farm.shard-")?
        .strip_suffix(".json")?;
    let (k, n) = rest.split_once("-of-")?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(k) || !digits(n) {
        return None;
    }
    Some((k.parse().ok()?, n.parse().ok()?))
}

impl ShardManifest {
    /// Where this manifest goes in `dir`.
    pub(crate) fn path_in(&self, dir: &Path) -> PathBuf {
        dir.join(file_name(self.shard, self.shards))
    }

    /// Writes the manifest into `dir` atomically (a temporary, synced, then moved over the
    /// shard's previous manifest, which is this shard's own record) through `session`, which
    /// must replace existing outputs.
    pub(crate) fn write(
        &self,
        dir: &Path,
        session: &nsrm_output::Session,
    ) -> Result<PathBuf, FarmError> {
        let path = self.path_in(dir);
        let mut json = serde_json::to_vec_pretty(self).map_err(|e| FarmError::Format {
            path: path.clone(),
            why: e.to_string(),
        })?;
        json.push(b'\n');
        session.write_bytes(&path, &json)?;
        Ok(path)
    }

    /// Reads a manifest, checking its format.
    pub(crate) fn read(path: &Path) -> Result<ShardManifest, FarmError> {
        let bytes = read_bounded(path, MAX_RECORD_BYTES)?;
        let bad = |why: String| FarmError::Format {
            path: path.to_path_buf(),
            why,
        };
        let m: ShardManifest = serde_json::from_slice(&bytes)
            .map_err(|e| bad(format!("not a shard manifest: {e}")))?;
        if m.format != FORMAT {
            return Err(bad(format!(
                "manifest format `{}`; this nsrm reads `{FORMAT}`",
                m.format
            )));
        }
        if m.shards > super::MAX_SHARDS {
            return Err(bad(format!(
                "{} shards; a batch has at most {}",
                m.shards,
                super::MAX_SHARDS
            )));
        }
        if m.shards == 0 || m.shard == 0 || m.shard > m.shards {
            return Err(bad(format!(
                "shard {}/{} is not a shard",
                m.shard, m.shards
            )));
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_names_round_trip_and_others_are_refused() {
        assert_eq!(file_name(2, 8), "nsrm-farm.shard-0002-of-0008.json");
        assert_eq!(parse_file_name(&file_name(2, 8)), Some((2, 8)));
        assert_eq!(
            parse_file_name(&file_name(12345, 99999)),
            Some((12345, 99999))
        );
        for bad in [
            "nsrm-farm.shard-0002-of-.json",
            "nsrm-farm.shard-x-of-2.json",
            "shot_xyz.0001.exr",
            "nsrm-farm.shard-0002-of-0008.json.tmp",
        ] {
            assert_eq!(parse_file_name(bad), None, "{bad}");
        }
    }

    #[test]
    fn the_batch_identity_depends_on_names_and_order() {
        let a = Batch::of(&["a.exr", "b.exr"]);
        assert_eq!(a, Batch::of(&["a.exr".to_string(), "b.exr".to_string()]));
        assert_ne!(a, Batch::of(&["b.exr", "a.exr"]));
        assert_ne!(a, Batch::of(&["a.exr"]));
        assert_eq!(a.inputs, 2);
    }
}
