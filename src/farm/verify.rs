//! Checks that a batch run on a farm is whole.

use super::manifest::{parse_file_name, Batch, ShardManifest};
use super::{sha256_file, FarmError};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// What to expect beyond what the manifests say.
#[derive(Debug, Clone, Default)]
pub(crate) struct Expect {
    /// The shard count the job was made with.
    pub shards: Option<usize>,
    /// The SHA-256 of the model the job applies.
    pub model_sha256: Option<String>,
}

/// What [`verify`] found.
#[derive(Debug, Clone, Default)]
pub(crate) struct Report {
    /// Manifests read.
    pub manifests: usize,
    /// Shards of the batch (as the manifests say).
    pub shards: usize,
    /// Inputs of the batch.
    pub inputs: usize,
    /// Outputs whose size and hash were checked and matched.
    pub outputs_ok: usize,
    /// Bytes hashed.
    pub bytes: u64,
    /// What is missing or wrong, one line each; empty when the batch is whole.
    pub problems: Vec<String>,
}

impl Report {
    /// Whether the batch is whole.
    pub(crate) fn ok(&self) -> bool {
        self.problems.is_empty()
    }
}

/// Reads every shard manifest in `dir` and checks: every shard `1..=N` has exactly one
/// manifest, all from one batch, one model and the same settings; no shard reports a failure;
/// each input of the batch has exactly one output; every output (and preview) is there with
/// the size and SHA-256 its manifest records; and no nsrm temporary is left in `dir`. Errors
/// only when `dir` cannot be listed; everything else is a problem in the report.
pub(crate) fn verify(dir: &Path, expect: &Expect) -> Result<Report, FarmError> {
    let mut r = Report::default();
    let mut found: Vec<(usize, usize, PathBuf)> = Vec::new();
    let listing = std::fs::read_dir(dir).map_err(|err| FarmError::Io {
        path: dir.to_path_buf(),
        err,
    })?;
    for e in listing.flatten() {
        if let Some((k, n)) = e.file_name().to_str().and_then(parse_file_name) {
            found.push((k, n, e.path()));
        }
    }
    found.sort();
    let mut manifests: Vec<ShardManifest> = Vec::new();
    for (k, n, path) in &found {
        match ShardManifest::read(path) {
            Ok(m) if (m.shard, m.shards) == (*k, *n) => manifests.push(m),
            Ok(m) => r.problems.push(format!(
                "{}: records shard {}/{}, not the {k}/{n} its name says",
                path.display(),
                m.shard,
                m.shards
            )),
            Err(e) => r.problems.push(e.to_string()),
        }
    }
    r.manifests = manifests.len();
    let Some(first) = manifests.first() else {
        r.problems.push(format!(
            "{}: no shard manifest (no shard has finished here)",
            dir.display()
        ));
        return Ok(with_temporaries(r, dir));
    };
    let n = expect.shards.unwrap_or(first.shards);
    r.shards = n;
    let batch: Batch = first.batch.clone();
    r.inputs = batch.inputs;
    let model = expect
        .model_sha256
        .clone()
        .unwrap_or_else(|| first.model.sha256.clone());

    let mut by_shard: HashMap<usize, &ShardManifest> = HashMap::new();
    for m in &manifests {
        let name = super::manifest::file_name(m.shard, m.shards);
        if m.shards != n {
            r.problems.push(format!(
                "{name}: made for {} shards, the batch has {n}",
                m.shards
            ));
            continue;
        }
        if m.batch != batch {
            r.problems.push(format!(
                "{name}: from another batch ({} inputs, outputs {}) than {} ({} inputs, outputs {})",
                m.batch.inputs,
                short(&m.batch.outputs_sha256),
                super::manifest::file_name(first.shard, first.shards),
                batch.inputs,
                short(&batch.outputs_sha256)
            ));
        }
        if m.model.sha256 != model {
            r.problems.push(format!(
                "{name}: applied another model ({} sha256 {}, expected {})",
                m.model.path,
                short(&m.model.sha256),
                short(&model)
            ));
        }
        if m.settings != first.settings {
            r.problems.push(format!(
                "{name}: converted with other settings ({}) than the rest ({})",
                m.settings.join(" "),
                first.settings.join(" ")
            ));
        }
        for f in &m.failures {
            r.problems
                .push(format!("{name}: {} was not converted: {}", f.input, f.why));
        }
        by_shard.insert(m.shard, m);
    }
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let mut names: Vec<Option<&str>> = vec![None; batch.inputs];
    for k in 1..=n {
        let Some(m) = by_shard.get(&k) else {
            let count = (0..batch.inputs).filter(|i| i % n == k - 1).count();
            r.problems.push(format!(
                "shard {k}/{n}: no manifest ({count} input(s) of the batch unaccounted for; run or re-run that shard)"
            ));
            continue;
        };
        let expected = (0..batch.inputs).filter(|i| i % n == k - 1).count();
        let done = m.outputs.len();
        if done + m.failures.len() != expected {
            r.problems.push(format!(
                "shard {k}/{n}: {done} output(s) and {} failure(s) recorded for {expected} input(s)",
                m.failures.len()
            ));
        }
        for (j, e) in m.outputs.iter().enumerate() {
            if let Some(slot) = names.get_mut(k - 1 + j * n) {
                *slot = Some(&e.output);
            }
            if let Some(other) = seen.insert(&e.output, k) {
                r.problems.push(format!(
                    "{}: recorded by shard {other}/{n} and by shard {k}/{n}",
                    e.output
                ));
            }
            let out = dir.join(&e.output);
            if !out.is_file() {
                r.problems.push(format!(
                    "{}: missing (the output of {}, shard {k}/{n})",
                    out.display(),
                    e.input
                ));
                continue;
            }
            match check_file(&out, e.bytes, &e.sha256) {
                Ok(b) => {
                    r.bytes += b;
                    r.outputs_ok += 1;
                }
                Err(why) => r.problems.push(format!("{}: {why}", out.display())),
            }
            if let Some(p) = &e.preview {
                if let Err(why) = check_file(Path::new(&p.path), p.bytes, &p.sha256) {
                    r.problems
                        .push(format!("{} (preview of {}): {why}", p.path, e.output));
                }
            }
        }
    }
    let complete: Option<Vec<&str>> = names.into_iter().collect();
    if let Some(all) = complete {
        if Batch::of(&all) != batch {
            r.problems.push(
                "the outputs recorded are not the batch's (names or order differ from the batch the shards were given)".into(),
            );
        }
    }
    Ok(with_temporaries(r, dir))
}

fn with_temporaries(mut r: Report, dir: &Path) -> Report {
    for t in crate::output::stale_temporaries(dir) {
        r.problems.push(format!(
            "{}: an nsrm temporary is left (a task was killed; re-run its shard, which removes it)",
            t.display()
        ));
    }
    r
}

fn check_file(path: &Path, bytes: u64, sha256: &str) -> Result<u64, String> {
    let (size, hash) = sha256_file(path).map_err(|e| e.to_string())?;
    if size != bytes {
        return Err(format!("{size} bytes, the manifest records {bytes}"));
    }
    if hash != sha256 {
        return Err(format!(
            "sha256 {}, the manifest records {} (changed since it was written)",
            short(&hash),
            short(sha256)
        ));
    }
    Ok(size)
}

fn short(h: &str) -> &str {
    h.get(..12).unwrap_or(h)
}
