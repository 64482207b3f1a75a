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
///
/// The steps: the manifests read (`read_manifests`), checked against each other
/// (`agreeing_shards`), each shard's outputs checked on disk (`check_shard`), and the
/// outputs' names against the batch's identity.
pub(crate) fn verify(dir: &Path, expect: &Expect) -> Result<Report, FarmError> {
    let mut r = Report::default();
    let manifests = read_manifests(dir, &mut r.problems)?;
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
    let by_shard = agreeing_shards(&manifests, n, &model, &mut r.problems);
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let mut names: Vec<Option<&str>> = vec![None; batch.inputs];
    for k in 1..=n {
        match by_shard.get(&k).copied() {
            Some(m) => check_shard(dir, m, n, &mut r, &mut seen, &mut names),
            None => r.problems.push(format!(
                "shard {k}/{n}: no manifest ({} input(s) of the batch unaccounted for; run or re-run that shard)",
                shard_share(batch.inputs, n, k)
            )),
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

/// The shard manifests in `dir`, in shard order; one that does not read, or whose content names
/// another shard than its file name, is a problem instead.
fn read_manifests(dir: &Path, problems: &mut Vec<String>) -> Result<Vec<ShardManifest>, FarmError> {
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
            Ok(m) => problems.push(format!(
                "{}: records shard {}/{}, not the {k}/{n} its name says",
                path.display(),
                m.shard,
                m.shards
            )),
            Err(e) => problems.push(e.to_string()),
        }
    }
    Ok(manifests)
}

/// The manifests of `n` shards by shard: each must be of the first manifest's batch, applied
/// `model` with the first's settings and report no failure (each difference a problem); one made
/// for another shard count is left out.
fn agreeing_shards<'m>(
    manifests: &'m [ShardManifest],
    n: usize,
    model: &str,
    problems: &mut Vec<String>,
) -> HashMap<usize, &'m ShardManifest> {
    let mut by_shard: HashMap<usize, &ShardManifest> = HashMap::new();
    let Some(first) = manifests.first() else {
        return by_shard;
    };
    let batch = &first.batch;
    for m in manifests {
        let name = super::manifest::file_name(m.shard, m.shards);
        if m.shards != n {
            problems.push(format!(
                "{name}: made for {} shards, the batch has {n}",
                m.shards
            ));
            continue;
        }
        if &m.batch != batch {
            problems.push(format!(
                "{name}: from another batch ({} inputs, outputs {}) than {} ({} inputs, outputs {})",
                m.batch.inputs,
                short(&m.batch.outputs_sha256),
                super::manifest::file_name(first.shard, first.shards),
                batch.inputs,
                short(&batch.outputs_sha256)
            ));
        }
        if m.model.sha256 != model {
            problems.push(format!(
                "{name}: applied another model ({} sha256 {}, expected {})",
                m.model.path,
                short(&m.model.sha256),
                short(model)
            ));
        }
        if m.settings != first.settings {
            problems.push(format!(
                "{name}: converted with other settings ({}) than the rest ({})",
                m.settings.join(" "),
                first.settings.join(" ")
            ));
        }
        for f in &m.failures {
            problems.push(format!("{name}: {} was not converted: {}", f.input, f.why));
        }
        by_shard.insert(m.shard, m);
    }
    by_shard
}

/// How many of a batch's `inputs` shard `k` of `n` converts (input `i` goes to shard
/// `i % n + 1`).
fn shard_share(inputs: usize, n: usize, k: usize) -> usize {
    (0..inputs).filter(|i| i % n == k - 1).count()
}

/// Checks shard `m` (of `n`): its outputs and failures account for its share of the inputs, no
/// output is recorded by two shards (`seen`: output → shard), each output (and preview) is on
/// disk in `dir` with its recorded size and hash; each output's name goes to its batch place in
/// `names`.
fn check_shard<'m>(
    dir: &Path,
    m: &'m ShardManifest,
    n: usize,
    r: &mut Report,
    seen: &mut HashMap<&'m str, usize>,
    names: &mut [Option<&'m str>],
) {
    let k = m.shard;
    let expected = shard_share(names.len(), n, k);
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

#[cfg(test)]
mod tests {
    use super::super::manifest::{Entry, Failure, How, ModelRecord, Timings, FORMAT};
    use super::*;

    /// Shard `k` of `n` of a batch of `names`, having written the outputs it names.
    fn manifest(k: usize, n: usize, names: &[&str], outputs: &[(&str, &[u8])]) -> ShardManifest {
        ShardManifest {
            format: FORMAT.into(),
            nsrm_version: "0".into(),
            shard: k,
            shards: n,
            batch: Batch::of(names),
            model: ModelRecord {
                path: "m.json".into(),
                sha256: "aa".repeat(32),
            },
            settings: vec!["--output-space".into(), "acescg".into()],
            outputs: outputs
                .iter()
                .map(|(name, bytes)| Entry {
                    input: format!("in/{name}"),
                    output: name.to_string(),
                    bytes: bytes.len() as u64,
                    sha256: super::super::sha256_bytes(bytes),
                    preview: None,
                    how: How::Converted,
                })
                .collect(),
            failures: Vec::new(),
            stale_temporaries_removed: Vec::new(),
            timings: Timings::default(),
        }
    }

    #[test]
    fn shards_take_every_nth_input() {
        assert_eq!(
            (1..=3).map(|k| shard_share(10, 3, k)).collect::<Vec<_>>(),
            [4, 3, 3]
        );
        assert_eq!(shard_share(1, 4, 4), 0);
    }

    #[test]
    fn manifests_that_disagree_with_the_first_are_problems() {
        let names = ["a.exr", "b.exr"];
        let model = "aa".repeat(32);
        let mut other_settings = manifest(2, 2, &names, &[]);
        other_settings.settings.clear();
        let mut failed = manifest(2, 2, &names, &[]);
        failed.failures.push(Failure {
            input: "in/b.exr".into(),
            output: "b.exr".into(),
            why: "unreadable".into(),
        });
        let all = [
            manifest(1, 2, &names, &[]),
            manifest(1, 3, &names, &[]),
            manifest(2, 2, &["x.exr"], &[]),
            other_settings,
            failed,
        ];
        let mut problems = Vec::new();
        let by = agreeing_shards(&all, 2, &model, &mut problems);
        assert_eq!(problems.len(), 4, "{problems:#?}");
        assert!(problems[0].contains("made for 3 shards"));
        assert!(problems[1].contains("another batch"));
        assert!(problems[2].contains("other settings"));
        assert!(problems[3].contains("unreadable"));
        assert_eq!(by.len(), 2);
        let mut problems = Vec::new();
        agreeing_shards(&all[..1], 2, "bb", &mut problems);
        assert!(problems[0].contains("another model"), "{problems:?}");
    }

    #[test]
    fn a_shards_outputs_are_checked_on_disk() {
        let dir = std::env::temp_dir().join(format!("nsrm-verify-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.exr"), b"right").unwrap();
        std::fs::write(dir.join("c.exr"), b"wrong").unwrap();
        let names = ["a.exr", "b.exr", "c.exr", "d.exr"];
        let m = manifest(1, 2, &names, &[("a.exr", b"right"), ("c.exr", b"other")]);
        let mut r = Report::default();
        let (mut seen, mut slots) = (HashMap::new(), vec![None; 4]);
        check_shard(&dir, &m, 2, &mut r, &mut seen, &mut slots);
        assert_eq!((r.outputs_ok, r.bytes), (1, 5));
        assert_eq!(r.problems.len(), 1, "{:?}", r.problems);
        assert!(r.problems[0].contains("sha256"), "{:?}", r.problems);
        assert_eq!(slots, [Some("a.exr"), None, Some("c.exr"), None]);
        // Shard 2 records `a.exr` again (twice recorded) and an output that is not there.
        let again = manifest(2, 2, &names, &[("a.exr", b"right"), ("x.exr", b"")]);
        let mut r = Report::default();
        check_shard(&dir, &again, 2, &mut r, &mut seen, &mut slots);
        assert!(r
            .problems
            .iter()
            .any(|p| p.contains("recorded by shard 1/2")));
        assert!(r.problems.iter().any(|p| p.contains("missing")));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
