//! Batches: expanding command-line inputs into a sorted list of frames, slicing it for
//! `--shard`, and naming (and checking) outputs; and the executor that runs a plan (decode →
//! correct → encode on threads, events to the caller: [`execute`]).

pub use super::batch_exec::{
    execute, Correct, CorrectError, Encoder, Event, ExecOptions, Executed, Files, FrameError,
    FrameOutcome, FrameSink, ModelCorrector, Timing,
};
use super::{FileFormat, IoError};
use std::collections::{HashMap, HashSet};
use std::ffi::{OsStr, OsString};
use std::io::ErrorKind;
use std::path::{Component, Path, PathBuf};

/// Whether a file name looks like a frame nsrm reads: `.exr`, `.tif`, `.tiff` or a camera raw
/// file's extension ([`super::raw::RAW_EXTENSIONS`]; any case), not
/// hidden (so `._x.exr` AppleDouble files and nsrm's own `.x.tmp` files are left out). The
/// rest of the name may be anything, UTF-8 or not.
pub(crate) fn is_frame_name(path: &Path) -> bool {
    let hidden = path
        .file_name()
        .is_none_or(|n| n.as_encoded_bytes().first() == Some(&b'.'));
    !hidden && (FileFormat::from_extension(path).is_some() || super::raw::is_raw_name(path))
}

/// Whether a directory entry or glob match is taken: frame names that are not directories
/// (a FIFO or a dangling link named `x.exr` is taken, and fails alone when read, so it is
/// reported rather than silently left out).
fn take_entry(p: &Path) -> bool {
    is_frame_name(p) && !p.is_dir()
}

/// Expands inputs into a sorted, de-duplicated list of files:
/// * an existing file is taken as it is (its format is told by its content when read);
/// * a directory gives its EXR/TIFF files (not those of its subdirectories);
/// * anything else is a glob pattern (`shots/*.exr`, `plate.[0-9]*.tif`), whose matches are
///   filtered to EXR/TIFF file names.
///
/// An input that matches nothing is an error, naming it; one that exists but is neither a
/// regular file nor a directory is an error saying what it is. Names need not be UTF-8, in a
/// directory, a glob match (in any component) or the pattern itself (see `glob_into`). Files reached twice (two patterns, or `./a.exr` and `a.exr`)
/// are listed once. The list is sorted by path, so every machine given the same inputs sees
/// the same order (see [`Shard`]).
pub fn expand_inputs<S: AsRef<std::ffi::OsStr>>(specs: &[S]) -> Result<Vec<PathBuf>, IoError> {
    let mut found: Vec<PathBuf> = Vec::new();
    for spec in specs {
        let path = Path::new(spec.as_ref());
        let shown = || path.display().to_string();
        let before = found.len();
        let meta = std::fs::metadata(path);
        if let Err(e) = &meta {
            if e.kind() == std::io::ErrorKind::PermissionDenied {
                return Err(IoError::NoMatch {
                    spec: shown(),
                    why: "permission denied (a folder on its path cannot be searched by this user)"
                        .into(),
                });
            }
        }
        if let Ok(meta) = meta {
            if meta.is_file() {
                found.push(path.to_path_buf());
                continue;
            }
            if !meta.is_dir() {
                return Err(IoError::NoMatch {
                    spec: shown(),
                    why: format!(
                        "not a regular file (it is {})",
                        nsrm::limits::file_kind(&meta)
                    ),
                });
            }
            let entries = std::fs::read_dir(path).map_err(|err| IoError::Read {
                path: path.to_path_buf(),
                err,
            })?;
            for e in entries {
                let e = e.map_err(|err| IoError::Read {
                    path: path.to_path_buf(),
                    err,
                })?;
                let p = e.path();
                if take_entry(&p) {
                    found.push(p);
                }
            }
            if found.len() == before {
                return Err(IoError::NoMatch {
                    spec: shown(),
                    why: "the directory holds no .exr, .tif or .tiff files".into(),
                });
            }
            continue;
        }
        if std::fs::symlink_metadata(path).is_ok() {
            return Err(IoError::NoMatch {
                spec: shown(),
                why: "a symbolic link to nothing (its target does not exist)".into(),
            });
        }
        let pattern = spec.as_ref();
        if !has_glob_bytes(pattern.as_encoded_bytes()) {
            return Err(IoError::NoMatch {
                spec: shown(),
                why: "no such file or directory".into(),
            });
        }
        glob_into(pattern, &mut found)?;
        if found.len() == before {
            return Err(IoError::NoMatch {
                spec: shown(),
                why: "the pattern matches no .exr, .tif or .tiff files".into(),
            });
        }
    }
    found.sort();
    let mut seen = HashSet::new();
    found.retain(|p| seen.insert(std::fs::canonicalize(p).unwrap_or_else(|_| p.clone())));
    Ok(found)
}

/// Adds the matches of a glob pattern, walking the directories here (not with the `glob` crate,
/// which skips names that are not UTF-8). Each component of the pattern is matched against the
/// names' bytes:
///
/// * `*` any run of characters, `?` one character, `[abc]` / `[a-z]` / `[!abc]` one character
///   of (not of) a set; a byte that is not part of valid UTF-8 counts as one character, matched by
///   `?`, `*` and `[!…]`, or by the same byte in the pattern; a leading `.` must be matched
///   literally (hidden files and directories are left out);
/// * `**` as a whole component: this directory and every directory below it (symbolic links to
///   directories are not followed there, so a loop cannot trap the walk);
/// * a component without wildcards is taken as it is.
///
/// Names that are not UTF-8 are therefore matched like any other, in a directory part as in the
/// file name, and the pattern itself may be non-UTF-8.
fn glob_into(pattern: &OsStr, found: &mut Vec<PathBuf>) -> Result<(), IoError> {
    let shown = || Path::new(pattern).display().to_string();
    let mut current: Vec<PathBuf> = vec![PathBuf::new()];
    let comps: Vec<Component> = Path::new(pattern).components().collect();
    for (k, comp) in comps.iter().enumerate() {
        let last = k + 1 == comps.len();
        let name = match comp {
            Component::Normal(n) => *n,
            other => {
                for c in &mut current {
                    c.push(other.as_os_str());
                }
                continue;
            }
        };
        let bytes = name.as_encoded_bytes();
        let mut next = Vec::new();
        if !has_glob_bytes(bytes) {
            for c in &current {
                let p = c.join(name);
                if last || p.is_dir() {
                    next.push(p);
                }
            }
        } else if bytes == b"**" {
            for c in &current {
                walk_dirs(c, &mut next)?;
            }
            if last {
                // `dir/**` names directories only; frames are files.
                next.clear();
            }
        } else {
            let pat = Pattern::parse(bytes).map_err(|why| IoError::NoMatch {
                spec: shown(),
                why: format!("bad pattern: {why}"),
            })?;
            for c in &current {
                let dir = if c.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    c.as_path()
                };
                let entries = match std::fs::read_dir(dir) {
                    Ok(e) => e,
                    Err(e)
                        if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::NotADirectory) =>
                    {
                        continue
                    }
                    Err(err) => {
                        return Err(IoError::Read {
                            path: dir.to_path_buf(),
                            err,
                        })
                    }
                };
                let mut names: Vec<OsString> = entries.flatten().map(|e| e.file_name()).collect();
                names.sort();
                for n in names {
                    if pat.matches(n.as_encoded_bytes()) {
                        let p = c.join(&n);
                        if last || p.is_dir() {
                            next.push(p);
                        }
                    }
                }
            }
        }
        current = next;
        if current.is_empty() {
            return Ok(());
        }
    }
    found.extend(current.into_iter().filter(|p| take_entry(p)));
    Ok(())
}

fn has_glob_bytes(b: &[u8]) -> bool {
    b.iter().any(|c| matches!(c, b'*' | b'?' | b'['))
}

/// `dir` and every directory below it (not hidden, symbolic links not followed), sorted
/// (walkdir, sorted by name, depth first). Directories that cannot be read are left out.
fn walk_dirs(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), IoError> {
    let root = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let walk = walkdir::WalkDir::new(root)
        .follow_links(false)
        .sort_by_file_name()
        .into_iter()
        .filter_entry(|e| {
            e.depth() == 0
                || (e.file_type().is_dir()
                    && e.file_name().as_encoded_bytes().first() != Some(&b'.'))
        });
    for e in walk.flatten() {
        if e.depth() == 0 {
            out.push(dir.to_path_buf());
        } else if e.file_type().is_dir() {
            // Keep the pattern's form: `dir/sub…` (no `./` added).
            out.push(dir.join(e.path().strip_prefix(root).unwrap_or(e.path())));
        }
    }
    Ok(())
}

/// One unit of a name: a character, or a byte that is not part of valid UTF-8.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Unit {
    Char(char),
    Byte(u8),
}

fn units(b: &[u8]) -> Vec<Unit> {
    let mut out = Vec::with_capacity(b.len());
    for chunk in b.utf8_chunks() {
        out.extend(chunk.valid().chars().map(Unit::Char));
        out.extend(chunk.invalid().iter().map(|&x| Unit::Byte(x)));
    }
    out
}

#[derive(Debug, Clone, PartialEq)]
enum Token {
    Literal(Unit),
    One,
    Star,
    /// `[…]`: ranges (inclusive), negated with `[!…]`.
    Set(bool, Vec<(Unit, Unit)>),
}

/// A compiled pattern for one path component.
#[derive(Debug, Clone)]
struct Pattern(Vec<Token>);

impl Pattern {
    fn parse(b: &[u8]) -> Result<Pattern, String> {
        let u = units(b);
        let mut t = Vec::new();
        let mut i = 0;
        while i < u.len() {
            match u[i] {
                Unit::Char('*') => {
                    if t.last() != Some(&Token::Star) {
                        t.push(Token::Star);
                    }
                    i += 1;
                }
                Unit::Char('?') => {
                    t.push(Token::One);
                    i += 1;
                }
                Unit::Char('[') => {
                    let mut j = i + 1;
                    let negated = matches!(u.get(j), Some(Unit::Char('!' | '^')));
                    if negated {
                        j += 1;
                    }
                    let mut items = Vec::new();
                    let mut first = true;
                    loop {
                        let Some(&c) = u.get(j) else {
                            return Err(format!("`[` at character {} is not closed", i + 1));
                        };
                        if c == Unit::Char(']') && !first {
                            j += 1;
                            break;
                        }
                        first = false;
                        if u.get(j + 1) == Some(&Unit::Char('-'))
                            && u.get(j + 2).is_some_and(|&e| e != Unit::Char(']'))
                        {
                            let e = u[j + 2];
                            if e < c {
                                return Err("a range in `[…]` runs backwards".into());
                            }
                            items.push((c, e));
                            j += 3;
                        } else {
                            items.push((c, c));
                            j += 1;
                        }
                    }
                    t.push(Token::Set(negated, items));
                    i = j;
                }
                c => {
                    t.push(Token::Literal(c));
                    i += 1;
                }
            }
        }
        Ok(Pattern(t))
    }

    /// Whether a name (its bytes) matches; a leading `.` must be matched by a literal `.`.
    fn matches(&self, name: &[u8]) -> bool {
        let n = units(name);
        if n.first() == Some(&Unit::Char('.'))
            && self.0.first() != Some(&Token::Literal(Unit::Char('.')))
        {
            return false;
        }
        let one = |t: &Token, c: Unit| match t {
            Token::Literal(l) => *l == c,
            Token::One => true,
            Token::Set(neg, items) => {
                let inside = items.iter().any(|(a, b)| {
                    // Characters compare with characters, stray bytes with bytes.
                    std::mem::discriminant(a) == std::mem::discriminant(&c) && *a <= c && c <= *b
                });
                inside != *neg
            }
            Token::Star => false,
        };
        // Greedy matching with backtracking to the last `*` (linear in practice).
        let (p, mut pi, mut ni) = (&self.0, 0usize, 0usize);
        let mut back: Option<(usize, usize)> = None;
        while ni < n.len() {
            if pi < p.len() && p[pi] == Token::Star {
                back = Some((pi, ni));
                pi += 1;
            } else if pi < p.len() && one(&p[pi], n[ni]) {
                pi += 1;
                ni += 1;
            } else if let Some((bp, bn)) = back {
                pi = bp + 1;
                ni = bn + 1;
                back = Some((bp, bn + 1));
            } else {
                return false;
            }
        }
        while pi < p.len() && p[pi] == Token::Star {
            pi += 1;
        }
        pi == p.len()
    }
}

/// A deterministic slice of a batch: shard `index` of `count` (1-based, `1 ≤ index ≤ count`)
/// holds the inputs whose 0-based position `i` in the sorted list has `i % count == index - 1`.
/// The `count` shards are disjoint and together hold every input, so `count` machines given the
/// same inputs split the batch without talking to each other: a Slurm array `--array=1-N`
/// passes `--shard $SLURM_ARRAY_TASK_ID/N`; a Kubernetes indexed Job (indices from 0) passes
/// `--shard $((JOB_COMPLETION_INDEX + 1))/N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard's number, from 1.
    pub index: usize,
    /// How many shards the batch is split into.
    pub count: usize,
}

impl Shard {
    /// Parses `K/N` (1-based K).
    pub fn parse(spec: &str) -> Result<Shard, IoError> {
        let bad = |why: &str| IoError::Shard {
            spec: spec.to_string(),
            why: why.to_string(),
        };
        let (k, n) = spec
            .split_once('/')
            .ok_or_else(|| bad("expected K/N, e.g. 2/8 (K counts from 1)"))?;
        let k: usize = k
            .trim()
            .parse()
            .map_err(|_| bad("K is not a whole number"))?;
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| bad("N is not a whole number"))?;
        if n == 0 {
            return Err(bad("N must be at least 1"));
        }
        if k == 0 || k > n {
            return Err(bad(
                "K must be within 1..N (shards count from 1, like SLURM_ARRAY_TASK_ID with \
                 sbatch --array=1-N; for a 0-based index pass index+1)",
            ));
        }
        Ok(Shard { index: k, count: n })
    }

    /// Whether the input at 0-based position `i` belongs to this shard.
    pub(crate) fn contains(&self, i: usize) -> bool {
        i % self.count == self.index - 1
    }

    /// This shard's part of `items`, in order.
    #[cfg(test)]
    pub(crate) fn select<T: Clone>(&self, items: &[T]) -> Vec<T> {
        items
            .iter()
            .enumerate()
            .filter(|(i, _)| self.contains(*i))
            .map(|(_, t)| t.clone())
            .collect()
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The output file for `input`: `<stem><suffix>.<ext>` in `out_dir`, or beside the input. A
/// frame number ending the stem stays at the end, so sequences stay sequences:
/// `plate.0101.exr` → `plate_xyz.0101.exr`. Names are kept as they are (no lossy conversion:
/// a non-UTF-8 stem gives a non-UTF-8 output name).
pub(crate) fn output_path(
    input: &Path,
    out_dir: Option<&Path>,
    suffix: &str,
    format: FileFormat,
) -> PathBuf {
    let stem = input.file_stem().unwrap_or_default();
    let bytes = stem.as_encoded_bytes();
    let split = bytes.iter().rposition(|&b| b == b'.').filter(|&dot| {
        let frame = &bytes[dot + 1..];
        dot > 0 && !frame.is_empty() && frame.iter().all(u8::is_ascii_digit)
    });
    let mut name = OsString::new();
    match split {
        Some(dot) => {
            // Both halves are split at an ASCII '.', so each is valid in the OS encoding.
            let s = stem.to_string_lossy();
            if s.len() == bytes.len() {
                name.push(&s[..dot]);
                name.push(suffix);
                name.push(&s[dot..]);
            } else {
                let path = Path::new(stem);
                // Non-UTF-8: `Path::file_stem` on `base.frame` gives `base`, `extension` the frame.
                name.push(path.file_stem().unwrap_or_default());
                name.push(suffix);
                name.push(".");
                name.push(path.extension().unwrap_or_default());
            }
        }
        None => {
            name.push(stem);
            name.push(suffix);
        }
    }
    name.push(".");
    name.push(format.extension());
    match out_dir {
        Some(d) => d.join(name),
        None => input.with_file_name(name),
    }
}

/// Checks that `--suffix` is a plain fragment of a file name: no path separator, no `..`, no
/// NUL. (An empty suffix is allowed; the plan refuses it when an output would land on an input.)
pub fn validate_suffix(suffix: &str) -> Result<(), PlanError> {
    let bad = |why: &str| {
        Err(PlanError::Usage(format!(
            "output suffix `{suffix}`: {why}; it must be a plain part of a file name"
        )))
    };
    if suffix.contains('/') || suffix.contains('\\') {
        return bad("contains a path separator");
    }
    if suffix.contains("..") {
        return bad("contains `..`");
    }
    if suffix.contains('\0') {
        return bad("contains a NUL byte");
    }
    Ok(())
}

/// What to do about an output that already exists.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Existing {
    /// The input fails (`--overwrite` or `--skip-existing` is needed).
    #[default]
    Refuse,
    /// The input is skipped (`--skip-existing`).
    Skip,
    /// The output is replaced (`--overwrite`): only a regular file, never an input.
    Overwrite,
}

/// How a batch is planned.
#[derive(Debug, Clone, Default)]
pub struct PlanOptions<'a> {
    /// Output directory; `None`: beside each input.
    pub out_dir: Option<&'a Path>,
    /// Appended to each output's stem (see [`output_path`], [`validate_suffix`]).
    pub suffix: &'a str,
    /// The format written (it gives the extension).
    pub format: FileFormat,
    /// Where sRGB PNG previews go, if anywhere.
    pub preview_dir: Option<&'a Path>,
    /// What to do where an output exists.
    pub existing: Existing,
    /// This run's slice of the inputs; collisions are checked over all of them.
    pub shard: Option<Shard>,
    /// Create the output and preview directories (and check they can be written) before the
    /// paths are compared; `false` (a dry run) compares them as they would resolve.
    pub create_dirs: bool,
}

/// What the plan says to do with one input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Action {
    /// Correct the input into its output.
    Convert,
    /// Nothing to do, with the reason (the output exists and existing outputs are skipped).
    Skip(String),
    /// Fails before any work, with the reason.
    Fail(Refusal),
}

/// Why the plan refuses one input before any work (the front end adds how to change that).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// The output or preview path holds something that is not a regular file.
    #[error("{}: the {what} path is not a regular file (it is {kind}); nsrm never replaces one", path.display())]
    NotRegular {
        /// The path.
        path: PathBuf,
        /// `output` or `preview`.
        what: &'static str,
        /// What is there instead (a directory, a symbolic link, …).
        kind: &'static str,
    },
    /// The output exists and existing outputs are refused.
    #[error("{}: already exists (not replaced)", .0.display())]
    Exists(PathBuf),
    /// The preview exists and existing outputs are refused.
    #[error("{}: preview already exists (not replaced)", .0.display())]
    PreviewExists(PathBuf),
}

/// One input of the batch: where it goes and what to do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Job {
    /// The input frame.
    pub input: PathBuf,
    /// Where its corrected frame goes.
    pub output: PathBuf,
    /// Where its sRGB PNG preview goes, if one is asked for.
    pub preview: Option<PathBuf>,
    /// What to do with it.
    pub action: Action,
}

/// A checked batch: every output and preview resolved and compared with every input (by path
/// after resolving symlinks and `..`, and by device and inode), no two sharing a destination,
/// the policy for existing outputs applied, directories created.
#[derive(Debug, Clone)]
pub struct BatchPlan {
    /// This run's jobs (this shard's), in input order.
    pub jobs: Vec<Job>,
    /// Inputs of the whole batch (all shards).
    pub total_inputs: usize,
    /// This run's slice of the batch, if it is sharded.
    pub shard: Option<Shard>,
    /// The directories this run's outputs and previews go to, sorted (where a caller looks for
    /// what an earlier, killed run left behind).
    pub dirs: Vec<PathBuf>,
}

impl BatchPlan {
    /// Indices of the jobs to convert.
    pub fn to_convert(&self) -> Vec<usize> {
        (0..self.jobs.len())
            .filter(|&i| self.jobs[i].action == Action::Convert)
            .collect()
    }

    /// `12 inputs` or `shard 2/4: 3 of 12 inputs`.
    pub fn scope(&self) -> String {
        match self.shard {
            Some(s) => format!(
                "shard {s}: {} of {} inputs",
                self.jobs.len(),
                self.total_inputs
            ),
            None => format!("{} inputs", self.jobs.len()),
        }
    }
}

/// Why a batch cannot be planned.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The options would lose data or contradict each other (exit status 2).
    #[error("{0}")]
    Usage(String),
    /// A directory cannot be created or written.
    #[error("{0}")]
    Setup(String),
}

impl PlanError {
    /// True for a batch that cannot be planned as asked (collisions, existing outputs, a bad
    /// suffix); false for a directory that cannot be set up.
    pub fn is_usage(&self) -> bool {
        matches!(self, PlanError::Usage(_))
    }
}

/// The path `p` will name once its missing directories exist: the longest existing prefix
/// resolved (symlinks, `.`, `..`), the rest applied lexically (components that do not exist
/// yet cannot be symlinks, so this is exact). Relative paths are taken from the current
/// directory.
pub(crate) fn resolve(p: &Path) -> PathBuf {
    use std::path::Component;
    let abs = if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_path_buf())
    };
    let comps: Vec<Component> = abs.components().collect();
    for k in (0..=comps.len()).rev() {
        let prefix: PathBuf = comps[..k].iter().collect();
        let Ok(mut out) = std::fs::canonicalize(&prefix) else {
            continue;
        };
        for c in &comps[k..] {
            match c {
                Component::ParentDir => {
                    out.pop();
                }
                Component::Normal(n) => out.push(n),
                _ => {}
            }
        }
        return out;
    }
    abs
}

/// Creates `dir` if needed and checks a file can be created in it (a probe with a temporary's
/// name, removed at once).
pub(crate) fn ensure_writable_dir(dir: &Path) -> Result<(), PlanError> {
    std::fs::create_dir_all(dir).map_err(|e| {
        PlanError::Setup(format!(
            "cannot create the output directory {}: {e}",
            dir.display()
        ))
    })?;
    // A fresh name (O_EXCL), removed when dropped.
    let probe = tempfile::Builder::new()
        .prefix(".nsrm-write-probe.")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| {
            PlanError::Setup(format!(
                "cannot write in the output directory {}: {e}",
                dir.display()
            ))
        })?;
    probe
        .close()
        .map_err(|e| PlanError::Setup(format!("cannot remove a probe in {}: {e}", dir.display())))
}

/// Plans a batch: pairs every input with its output (see [`output_path`]) and preview, creates
/// the directories (with `create_dirs`), and refuses a plan that could lose data: an output or
/// preview that is an input of the batch (by resolved path or by device and inode, so also
/// through symlinks, `..` and hard links), or two inputs sharing a destination. Existing
/// destinations follow `existing`; one that is not a regular file always fails its input.
pub fn plan_batch(inputs: &[PathBuf], o: &PlanOptions) -> Result<BatchPlan, PlanError> {
    validate_suffix(o.suffix)?;
    let format = o.format;
    let preview_of = |output: &Path| {
        o.preview_dir.map(|dir| {
            let name = output.with_extension("png");
            dir.join(name.file_name().unwrap_or_default())
        })
    };
    let all: Vec<(PathBuf, Option<PathBuf>)> = inputs
        .iter()
        .map(|i| {
            let out = output_path(i, o.out_dir, o.suffix, format);
            let prev = preview_of(&out);
            (out, prev)
        })
        .collect();
    let mine: Vec<usize> = (0..inputs.len())
        .filter(|&i| o.shard.is_none_or(|s| s.contains(i)))
        .collect();

    let mut dirs: Vec<PathBuf> = mine
        .iter()
        .flat_map(|&i| {
            [
                all[i].0.parent(),
                all[i].1.as_deref().and_then(Path::parent),
            ]
        })
        .flatten()
        .map(|d| {
            if d.as_os_str().is_empty() {
                PathBuf::from(".")
            } else {
                d.to_path_buf()
            }
        })
        .collect();
    dirs.sort();
    dirs.dedup();
    // Checked as the paths will resolve before anything is created (so a refused plan leaves
    // nothing behind), and again once the directories exist.
    check_destinations(inputs, &all)?;
    if o.create_dirs {
        for d in &dirs {
            ensure_writable_dir(d)?;
        }
        check_destinations(inputs, &all)?;
    }

    let jobs = mine
        .iter()
        .map(|&i| {
            let (output, preview) = all[i].clone();
            let action = existing_action(&output, preview.as_deref(), o.existing);
            Job {
                input: inputs[i].clone(),
                output,
                preview,
                action,
            }
        })
        .collect();
    Ok(BatchPlan {
        jobs,
        total_inputs: inputs.len(),
        shard: o.shard,
        dirs,
    })
}

/// Refuses outputs or previews that are inputs (by resolved path, or by device and inode when
/// they exist) and destinations shared by two inputs.
fn check_destinations(
    inputs: &[PathBuf],
    all: &[(PathBuf, Option<PathBuf>)],
) -> Result<(), PlanError> {
    let mut by_path: HashMap<PathBuf, usize> = HashMap::with_capacity(inputs.len());
    let mut by_id: HashMap<(u64, u64), usize> = HashMap::with_capacity(inputs.len());
    for (i, input) in inputs.iter().enumerate() {
        by_path.insert(resolve(input), i);
        if let Some(id) = std::fs::metadata(input)
            .ok()
            .as_ref()
            .and_then(nsrm::limits::file_id)
        {
            by_id.insert(id, i);
        }
    }
    let onto_input = |dest: &Path, what: &str, i: usize| -> Result<(), PlanError> {
        let hit = by_path.get(&resolve(dest)).copied().or_else(|| {
            std::fs::metadata(dest)
                .ok()
                .as_ref()
                .and_then(nsrm::limits::file_id)
                .and_then(|id| by_id.get(&id).copied())
        });
        match hit {
            None => Ok(()),
            Some(k) => Err(PlanError::Usage(format!(
                "{}: the {what} for {} would be written onto {}; choose another output suffix, output directory or preview directory",
                dest.display(),
                inputs[i].display(),
                if k == i {
                    "that input itself".to_string()
                } else {
                    format!("the input {}", inputs[k].display())
                }
            ))),
        }
    };
    let mut dests: HashMap<PathBuf, (usize, &str)> = HashMap::with_capacity(2 * inputs.len());
    for (i, (out, prev)) in all.iter().enumerate() {
        for (dest, what) in [(Some(out), "output"), (prev.as_ref(), "preview")] {
            let Some(dest) = dest else { continue };
            onto_input(dest, what, i)?;
            if let Some((k, other)) = dests.insert(resolve(dest), (i, what)) {
                return Err(PlanError::Usage(format!(
                    "{} and {} would both be written to {} (the {other} of one, the {what} of the other); \
                     convert them in separate runs or to separate -o directories",
                    inputs[k].display(),
                    inputs[i].display(),
                    dest.display()
                )));
            }
        }
    }

    Ok(())
}

fn existing_action(output: &Path, preview: Option<&Path>, existing: Existing) -> Action {
    let not_regular = |p: &Path, what: &'static str| {
        let meta = std::fs::metadata(p).ok()?;
        (!meta.is_file()).then(|| {
            Action::Fail(Refusal::NotRegular {
                path: p.to_path_buf(),
                what,
                kind: nsrm::limits::file_kind(&meta),
            })
        })
    };
    if let Some(a) = not_regular(output, "output") {
        return a;
    }
    if let Some(a) = preview.and_then(|p| not_regular(p, "preview")) {
        return a;
    }
    let exists = |p: &Path| std::fs::symlink_metadata(p).is_ok();
    if exists(output) {
        return match existing {
            Existing::Skip => Action::Skip(format!("{} exists (skipped)", output.display())),
            Existing::Refuse => Action::Fail(Refusal::Exists(output.to_path_buf())),
            Existing::Overwrite => Action::Convert,
        };
    }
    match preview {
        Some(p) if existing != Existing::Overwrite && exists(p) => {
            Action::Fail(Refusal::PreviewExists(p.to_path_buf()))
        }
        _ => Action::Convert,
    }
}

#[cfg(test)]
#[path = "batch_tests.rs"]
mod tests;
