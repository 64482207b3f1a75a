//! Checks that a batch run on a farm is whole.
//!
//! Nothing a manifest says is trusted: every file it names must be a plain name in the batch
//! directory (or, for previews, in the preview directory the caller gives) that resolves there
//! once symbolic links are followed; every count it states is checked against what the
//! manifests record instead of sizing anything; a shard count is bounded by [`MAX_SHARDS`].

use super::manifest::{parse_file_name, Batch, ShardManifest};
use super::{sha256_file, FarmError};
use std::collections::{BTreeMap, HashMap};
use std::path::{Component, Path, PathBuf};

use super::MAX_SHARDS;

/// What to expect beyond what the manifests say.
#[derive(Debug, Clone, Default)]
pub(crate) struct Expect {
    /// The shard count the job was made with.
    pub shards: Option<usize>,
    /// The SHA-256 of the model the job applies.
    pub model_sha256: Option<String>,
    /// Where the previews were written (the job's `--preview`); without it, a manifest that
    /// records previews is a problem (its paths are not trusted).
    pub preview_dir: Option<PathBuf>,
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

/// A directory a manifest's names are resolved in: as given, and with its symbolic links
/// resolved.
struct Root<'a> {
    dir: &'a Path,
    real: PathBuf,
}

impl<'a> Root<'a> {
    fn new(dir: &'a Path) -> Result<Root<'a>, FarmError> {
        let real = dir.canonicalize().map_err(|err| FarmError::Io {
            path: dir.to_path_buf(),
            err,
        })?;
        Ok(Root { dir, real })
    }

    /// `name` in this directory, when it is one plain file name there whose symbolic links
    /// (if any) resolve inside the directory; `Err` says why not. A name that is not there
    /// is returned as it is (a missing file is the caller's problem to report).
    fn resolve(&self, name: &str) -> Result<PathBuf, String> {
        let mut parts = Path::new(name).components();
        let plain = matches!(
            (parts.next(), parts.next()),
            (Some(Component::Normal(c)), None) if c == std::ffi::OsStr::new(name)
        );
        if !plain || name.contains('\0') {
            return Err(format!(
                "{}: not a file name in {} (a manifest names only files of its own directory)",
                shown(name),
                self.dir.display()
            ));
        }
        let path = self.dir.join(name);
        match path.canonicalize() {
            Ok(real) if real.starts_with(&self.real) => Ok(path),
            Ok(real) => Err(format!(
                "{}: a symbolic link leaving {} (to {}); refused",
                path.display(),
                self.dir.display(),
                real.display()
            )),
            Err(_) if path.symlink_metadata().is_ok() => Err(format!(
                "{}: a symbolic link that resolves nowhere; refused",
                path.display()
            )),
            Err(_) => Ok(path),
        }
    }
}

/// Text from a manifest as a problem line shows it: control characters escaped, so a crafted
/// name cannot rewrite the terminal or fake a line of the report.
fn shown(s: &str) -> String {
    if s.chars().any(char::is_control) {
        format!("{s:?}")
    } else {
        s.to_string()
    }
}

/// Reads every shard manifest in `dir` and checks: every shard `1..=N` has exactly one
/// manifest, all from one batch, one model and the same settings; no shard reports a failure;
/// each input of the batch has exactly one output; every output (and preview) is there with
/// the size and SHA-256 its manifest records; and no nsrm temporary is left in `dir`. Errors
/// only when `dir` cannot be listed or `expect` asks for more than [`MAX_SHARDS`]; everything
/// else is a problem in the report.
///
/// The steps: the manifests read (`read_manifests`), checked against each other
/// (`agreeing_shards`), each shard's outputs checked on disk (`check_shard`), the shards
/// without a manifest named as ranges (`missing_shards`), and the outputs' names against the
/// batch's identity. Nothing is sized by a count a manifest states.
pub(crate) fn verify(dir: &Path, expect: &Expect) -> Result<Report, FarmError> {
    if let Some(n) = expect.shards.filter(|&n| n == 0 || n > MAX_SHARDS) {
        return Err(FarmError::Usage(format!(
            "a shard count of {n}: a batch has 1 to {MAX_SHARDS} shards"
        )));
    }
    let root = Root::new(dir)?;
    let previews = match &expect.preview_dir {
        Some(p) => Some(Root::new(p)?),
        None => None,
    };
    let mut r = Report::default();
    let manifests = read_manifests(&root, &mut r.problems)?;
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
    // Batch place → output name, for the places the manifests fill (never sized by the
    // batch's stated input count).
    let mut names: BTreeMap<usize, &str> = BTreeMap::new();
    let places = Places {
        inputs: batch.inputs,
        n,
    };
    for (_, m) in by_shard.iter() {
        let dirs = Dirs {
            out: &root,
            previews: previews.as_ref(),
        };
        check_shard(&dirs, m, places, &mut r, &mut seen, &mut names);
    }
    missing_shards(&by_shard, places, &mut r.problems);
    if names.len() == batch.inputs {
        let all: Vec<&str> = names.into_values().collect();
        if Batch::of(&all) != batch {
            r.problems.push(
                "the outputs recorded are not the batch's (names or order differ from the batch the shards were given)".into(),
            );
        }
    }
    Ok(with_temporaries(r, dir))
}

/// Where a shard's files are: the batch's output directory and the previews' (when given).
struct Dirs<'r, 'a> {
    out: &'r Root<'a>,
    previews: Option<&'r Root<'a>>,
}

/// A batch's size and shard count, for the arithmetic of who converts what.
#[derive(Debug, Clone, Copy)]
struct Places {
    inputs: usize,
    n: usize,
}

impl Places {
    /// The batch place of shard `k`'s `j`-th output (input `i` goes to shard `i % n + 1`), if
    /// it is within the batch.
    fn place(self, k: usize, j: usize) -> Option<usize> {
        j.checked_mul(self.n)
            .and_then(|p| p.checked_add(k - 1))
            .filter(|&p| p < self.inputs)
    }
}

/// The shards `1..=n` without a manifest in `by_shard`, one problem per run of consecutive
/// missing shards (so a shard count of a million costs a line, not a million).
fn missing_shards(
    by_shard: &BTreeMap<usize, &ShardManifest>,
    p: Places,
    problems: &mut Vec<String>,
) {
    let mut next = 1usize;
    let ends = by_shard
        .keys()
        .copied()
        .filter(|&k| k <= p.n)
        .chain([p.n + 1]);
    for k in ends {
        if k > next {
            let (a, b) = (next, k - 1);
            let unaccounted = shares(p.inputs, p.n, a, b);
            problems.push(if a == b {
                format!(
                    "shard {a}/{n}: no manifest ({unaccounted} input(s) of the batch unaccounted for; run or re-run that shard)",
                    n = p.n
                )
            } else {
                format!(
                    "shards {a}-{b}/{n}: no manifest ({unaccounted} input(s) of the batch unaccounted for; run or re-run those shards)",
                    n = p.n
                )
            });
        }
        next = k + 1;
    }
}

/// The shard manifests in `dir`, in shard order; one that does not read, names a shard count
/// over [`MAX_SHARDS`], is not a file of `dir`, or whose content names another shard than its
/// file name, is a problem instead.
fn read_manifests(
    root: &Root,
    problems: &mut Vec<String>,
) -> Result<Vec<ShardManifest>, FarmError> {
    let mut found: Vec<(usize, usize, String)> = Vec::new();
    let listing = std::fs::read_dir(root.dir).map_err(|err| FarmError::Io {
        path: root.dir.to_path_buf(),
        err,
    })?;
    for e in listing.flatten() {
        let Some(name) = e.file_name().to_str().map(str::to_string) else {
            continue;
        };
        match parse_file_name(&name) {
            Some((_, n)) if n > MAX_SHARDS => problems.push(format!(
                "{}: a manifest of {n} shards; a batch has at most {MAX_SHARDS}",
                root.dir.join(&name).display()
            )),
            Some((k, n)) => found.push((k, n, name)),
            None => {}
        }
    }
    found.sort();
    let mut manifests: Vec<ShardManifest> = Vec::new();
    for (k, n, name) in &found {
        let path = match root.resolve(name) {
            Ok(p) => p,
            Err(why) => {
                problems.push(why);
                continue;
            }
        };
        match ShardManifest::read(&path) {
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
) -> BTreeMap<usize, &'m ShardManifest> {
    let mut by_shard: BTreeMap<usize, &ShardManifest> = BTreeMap::new();
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
                shown(short(&m.batch.outputs_sha256)),
                super::manifest::file_name(first.shard, first.shards),
                batch.inputs,
                shown(short(&batch.outputs_sha256))
            ));
        }
        if m.model.sha256 != model {
            problems.push(format!(
                "{name}: applied another model ({} sha256 {}, expected {})",
                shown(&m.model.path),
                shown(short(&m.model.sha256)),
                short(model)
            ));
        }
        if m.settings != first.settings {
            problems.push(format!(
                "{name}: converted with other settings ({}) than the rest ({})",
                shown(&m.settings.join(" ")),
                shown(&first.settings.join(" "))
            ));
        }
        for f in &m.failures {
            problems.push(format!(
                "{name}: {} was not converted: {}",
                shown(&f.input),
                shown(&f.why)
            ));
        }
        by_shard.insert(m.shard, m);
    }
    by_shard
}

/// How many of a batch's `inputs` shards `a..=b` of `n` convert together (input `i` goes to
/// shard `i % n + 1`), by arithmetic: no count is iterated.
fn shares(inputs: usize, n: usize, a: usize, b: usize) -> usize {
    // Shard k converts the inputs k-1, k-1+n, …: inputs / n of them, one more when
    // k-1 < inputs % n.
    let (whole, rest) = (inputs / n, inputs % n);
    let count = b + 1 - a;
    let extra = rest.min(b).saturating_sub(a - 1);
    whole.saturating_mul(count).saturating_add(extra)
}

/// How many of a batch's `inputs` shard `k` of `n` converts.
fn shard_share(inputs: usize, n: usize, k: usize) -> usize {
    shares(inputs, n, k, k)
}

/// Checks shard `m` (of `p.n`): its outputs and failures account for its share of the inputs,
/// no output is recorded by two shards (`seen`: output → shard), each output (and preview) is
/// a file of its directory with its recorded size and hash; each output's name goes to its
/// batch place in `names`. The problems name the manifest.
fn check_shard<'m>(
    dirs: &Dirs,
    m: &'m ShardManifest,
    p: Places,
    r: &mut Report,
    seen: &mut HashMap<&'m str, usize>,
    names: &mut BTreeMap<usize, &'m str>,
) {
    let (k, n) = (m.shard, p.n);
    let manifest = super::manifest::file_name(k, n);
    let expected = shard_share(p.inputs, n, k);
    let done = m.outputs.len();
    if done.saturating_add(m.failures.len()) != expected {
        r.problems.push(format!(
            "shard {k}/{n}: {done} output(s) and {} failure(s) recorded for {expected} input(s)",
            m.failures.len()
        ));
    }
    for (j, e) in m.outputs.iter().enumerate() {
        if let Some(place) = p.place(k, j) {
            names.insert(place, &e.output);
        }
        if let Some(other) = seen.insert(&e.output, k) {
            r.problems.push(format!(
                "{}: recorded by shard {other}/{n} and by shard {k}/{n}",
                shown(&e.output)
            ));
            continue;
        }
        let out = match dirs.out.resolve(&e.output) {
            Ok(out) => out,
            Err(why) => {
                r.problems.push(format!("{manifest}: output {why}"));
                continue;
            }
        };
        if !out.is_file() {
            r.problems.push(format!(
                "{}: missing (the output of {}, shard {k}/{n})",
                out.display(),
                shown(&e.input)
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
        if let Some(pv) = &e.preview {
            if let Err(why) = check_preview(dirs.previews, pv) {
                r.problems.push(format!(
                    "{manifest}: preview of {}: {why}",
                    shown(&e.output)
                ));
            }
        }
    }
}

/// Checks a recorded preview: its file name, in the preview directory given, with the size and
/// hash recorded. The directory the manifest records is not trusted.
fn check_preview(dir: Option<&Root>, pv: &super::manifest::Preview) -> Result<(), String> {
    let Some(dir) = dir else {
        return Err(format!(
            "{} recorded; give the job's preview directory to check it",
            shown(&pv.path)
        ));
    };
    let name = Path::new(&pv.path)
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| format!("{}: not a file's path", shown(&pv.path)))?;
    let path = dir.resolve(name)?;
    check_file(&path, pv.bytes, &pv.sha256)
        .map(drop)
        .map_err(|why| format!("{}: {why}", path.display()))
}

fn with_temporaries(mut r: Report, dir: &Path) -> Report {
    for t in nsrm_output::stale_temporaries(dir) {
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
            shown(short(sha256))
        ));
    }
    Ok(size)
}

fn short(h: &str) -> &str {
    // The first 12 characters (never a split character: a manifest's hash may be any text).
    match h.char_indices().nth(12) {
        Some((i, _)) => &h[..i],
        None => h,
    }
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
        let root = Root::new(&dir).unwrap();
        let dirs = Dirs {
            out: &root,
            previews: None,
        };
        let names = ["a.exr", "b.exr", "c.exr", "d.exr"];
        let p = Places { inputs: 4, n: 2 };
        let m = manifest(1, 2, &names, &[("a.exr", b"right"), ("c.exr", b"other")]);
        let mut r = Report::default();
        let (mut seen, mut slots) = (HashMap::new(), BTreeMap::new());
        check_shard(&dirs, &m, p, &mut r, &mut seen, &mut slots);
        assert_eq!((r.outputs_ok, r.bytes), (1, 5));
        assert_eq!(r.problems.len(), 1, "{:?}", r.problems);
        assert!(r.problems[0].contains("sha256"), "{:?}", r.problems);
        assert_eq!(
            slots.into_iter().collect::<Vec<_>>(),
            [(0, "a.exr"), (2, "c.exr")]
        );
        // Shard 2 records `a.exr` again (twice recorded) and an output that is not there.
        let again = manifest(2, 2, &names, &[("a.exr", b"right"), ("x.exr", b"")]);
        let mut r = Report::default();
        let mut slots = BTreeMap::new();
        check_shard(&dirs, &again, p, &mut r, &mut seen, &mut slots);
        assert!(r
            .problems
            .iter()
            .any(|p| p.contains("recorded by shard 1/2")));
        assert!(r.problems.iter().any(|p| p.contains("missing")));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn names_leaving_the_directory_are_refused_naming_the_manifest() {
        let base = std::env::temp_dir().join(format!("nsrm-verify-escape-{}", std::process::id()));
        let dir = base.join("out");
        std::fs::create_dir_all(&dir).unwrap();
        let secret = base.join("secret.txt");
        std::fs::write(&secret, b"secret").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(&secret, dir.join("link.exr")).unwrap();
        let root = Root::new(&dir).unwrap();
        let abs = secret.to_str().unwrap().to_string();
        let mut hostile = vec![
            "../secret.txt",
            abs.as_str(),
            "",
            ".",
            "..",
            "a/../../secret.txt",
        ];
        if cfg!(unix) {
            hostile.push("link.exr");
        }
        for name in &hostile {
            assert!(root.resolve(name).is_err(), "{name:?} accepted");
            let m = manifest(1, 1, &[name], &[(name, b"secret")]);
            let dirs = Dirs {
                out: &root,
                previews: None,
            };
            let mut r = Report::default();
            let (mut seen, mut slots) = (HashMap::new(), BTreeMap::new());
            check_shard(
                &dirs,
                &m,
                Places { inputs: 1, n: 1 },
                &mut r,
                &mut seen,
                &mut slots,
            );
            assert_eq!(r.outputs_ok, 0, "{name:?}");
            assert!(
                r.problems
                    .iter()
                    .any(|p| p.contains("nsrm-farm.shard-0001-of-0001.json")),
                "{name:?}: {:?}",
                r.problems
            );
        }
        assert!(root.resolve("plain.exr").is_ok());
        std::fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn shares_are_counted_without_iterating_the_batch() {
        for (inputs, n) in [(10, 3), (1, 4), (0, 2), (7, 7), (9, 2)] {
            for a in 1..=n {
                for b in a..=n {
                    let slow = (0..inputs)
                        .filter(|i| (a - 1..b).contains(&(i % n)))
                        .count();
                    assert_eq!(shares(inputs, n, a, b), slow, "{inputs} {n} {a}-{b}");
                }
            }
        }
        // A stated count of 2^64-1 costs nothing.
        assert_eq!(shard_share(usize::MAX, 1, 1), usize::MAX);
        let p = Places {
            inputs: usize::MAX,
            n: MAX_SHARDS,
        };
        assert_eq!(p.place(2, usize::MAX), None);
        let mut problems = Vec::new();
        missing_shards(&BTreeMap::new(), p, &mut problems);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(
            problems[0].starts_with("shards 1-100000/100000"),
            "{problems:?}"
        );
    }
}
