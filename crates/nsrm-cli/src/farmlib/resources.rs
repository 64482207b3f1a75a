//! What each task of a farm job asks its engine for, named once for every engine: CPUs,
//! memory, a wall-time limit and GPUs, plus what only one engine knows (a Slurm partition,
//! account and QOS; a Kubernetes node selector and tolerations; Open Job Description host
//! requirements), and a pass-through for each engine: extra `#SBATCH` lines, extra pod-spec
//! fields, further host requirements.
//!
//! Why one file (about 1,200 lines): each resource flag is parsed, checked and written for all
//! three engines in one place, so an engine cannot get a value another refuses. The tests are in
//! `resources_tests.rs`.
//!
//! Every value is checked here, before any file is written: numbers are bounded, names keep to
//! the characters their engine allows, and nothing can reach a script or a YAML document as
//! anything but the value it is (no line break, no quote a Slurm directive would misread).

use super::yaml::Pairs;
use super::FarmError;
use serde::Serialize;

/// The most CPUs or GPUs one task asks for.
pub(crate) const MAX_COUNT: u32 = 4096;
/// The least and most memory one task asks for, in MiB (16 MiB to 64 TiB).
pub(crate) const MIN_MEM_MIB: u64 = 16;
pub(crate) const MAX_MEM_MIB: u64 = 64 << 20;
/// The longest wall-time limit of a task: 365 days, in seconds.
pub(crate) const MAX_TIME_S: u64 = 365 * 24 * 3600;
/// The most values of one repeatable flag (node selectors, tolerations, `#SBATCH` lines, host
/// requirements).
pub(crate) const MAX_REPEATS: usize = 64;

/// The Kubernetes resource name of a GPU when `--gpu-resource` does not say (NVIDIA's device
/// plugin; AMD's is `amd.com/gpu`, Intel's `gpu.intel.com/i915`).
pub(crate) const KUBE_GPU: &str = "nvidia.com/gpu";

/// The largest value of one `--pod-spec` field, in bytes of JSON.
pub(crate) const MAX_POD_FIELD_BYTES: usize = 16 << 10;

/// The resources of one task, checked. `None` leaves a value to the engine's defaults.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Resources {
    pub cpus: Option<u32>,
    pub mem_mib: Option<u64>,
    pub time_s: Option<u64>,
    /// The verification's wall-time limit (it reads every output once).
    pub verify_time_s: Option<u64>,
    pub gpus: u32,
    /// The Kubernetes extended resource a GPU is asked for as; `None`: [`KUBE_GPU`].
    pub gpu_resource: Option<String>,
    pub partition: Option<String>,
    pub account: Option<String>,
    pub qos: Option<String>,
    /// Extra `#SBATCH` arguments, each one checked word (`--name` or `--name=value`).
    pub sbatch_args: Vec<String>,
    pub node_selector: Vec<(String, String)>,
    pub tolerations: Vec<Toleration>,
    /// Further pod-spec fields (`--pod-spec`), in the order given.
    pub pod_fields: Vec<(String, serde_json::Value)>,
    /// `attr.worker.os.family`: linux, windows or macos.
    pub os_family: Option<String>,
    /// Further Open Job Description host requirements.
    pub host_requirements: Vec<HostRequirement>,
}

/// A Kubernetes toleration, from `KEY[=VALUE][:EFFECT]` (kubectl taint's syntax): with a
/// value the operator is `Equal`, without one `Exists`; without an effect it tolerates every
/// effect.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Toleration {
    pub key: String,
    pub value: Option<String>,
    pub effect: Option<String>,
}

/// An Open Job Description host requirement: `amount.…=N` (at least N) or
/// `attr.…=V1,V2` (any of the values).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum HostRequirement {
    Amount { name: String, min: f64 },
    Attr { name: String, any_of: Vec<String> },
}

fn usage<T>(s: String) -> Result<T, FarmError> {
    Err(FarmError::Usage(s))
}

/// A count of CPUs or GPUs: 1 to [`MAX_COUNT`] (0 too for GPUs, `zero_ok`).
pub(crate) fn check_count(flag: &str, n: u32, zero_ok: bool) -> Result<u32, FarmError> {
    if n > MAX_COUNT || (n == 0 && !zero_ok) {
        return usage(format!(
            "{flag} {n}: a task asks for {} to {MAX_COUNT}",
            u32::from(!zero_ok)
        ));
    }
    Ok(n)
}

/// Memory as Slurm writes it: a whole number with an optional unit `K`, `M` (the default),
/// `G` or `T` (powers of 1024; `Ki`/`Mi`/`Gi`/`Ti` and a trailing `B` are accepted too), in
/// MiB, between [`MIN_MEM_MIB`] and [`MAX_MEM_MIB`].
pub(crate) fn parse_mem(s: &str) -> Result<u64, FarmError> {
    let bad = || {
        FarmError::Usage(format!(
            "--mem {s:?}: give a whole number with K, M, G or T (powers of 1024), e.g. 8G or 1500M, from {MIN_MEM_MIB}M to {}T",
            MAX_MEM_MIB >> 20
        ))
    };
    let t = s.trim();
    let digits = t.bytes().take_while(u8::is_ascii_digit).count();
    if digits == 0 || digits > 12 {
        return Err(bad());
    }
    let n: u64 = t[..digits].parse().map_err(|_| bad())?;
    let unit = t[digits..].to_ascii_uppercase();
    let unit = unit.strip_suffix('B').unwrap_or(&unit);
    let unit = unit.strip_suffix('I').unwrap_or(unit);
    let kib = match unit {
        "K" => n,
        "" | "M" => n.checked_mul(1 << 10).ok_or_else(bad)?,
        "G" => n.checked_mul(1 << 20).ok_or_else(bad)?,
        "T" => n.checked_mul(1 << 30).ok_or_else(bad)?,
        _ => return Err(bad()),
    };
    let mib = kib.div_ceil(1024);
    if !(MIN_MEM_MIB..=MAX_MEM_MIB).contains(&mib) {
        return Err(bad());
    }
    Ok(mib)
}

/// A wall-time limit in Slurm's syntax — `MINUTES`, `MINUTES:SECONDS`, `HOURS:MINUTES:SECONDS`,
/// `DAYS-HOURS`, `DAYS-HOURS:MINUTES`, `DAYS-HOURS:MINUTES:SECONDS` — in seconds, from 1 s to
/// 365 days.
pub(crate) fn parse_time(s: &str) -> Result<u64, FarmError> {
    parse_time_for("--time", s)
}

/// [`parse_time`] for the flag `flag` (named in the message).
pub(crate) fn parse_time_for(flag: &str, s: &str) -> Result<u64, FarmError> {
    let bad = |why: &str| {
        FarmError::Usage(format!(
            "{flag} {s:?}: {why}; Slurm's forms are MINUTES, MINUTES:SECONDS, HOURS:MINUTES:SECONDS, DAYS-HOURS, DAYS-HOURS:MINUTES or DAYS-HOURS:MINUTES:SECONDS (1 s to 365 days)"
        ))
    };
    let num = |p: &str| -> Result<u64, FarmError> {
        if p.is_empty() || p.len() > 9 || !p.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad("each part is a whole number"));
        }
        p.parse().map_err(|_| bad("each part is a whole number"))
    };
    let (days, rest) = match s.split_once('-') {
        Some((d, r)) => (Some(num(d)?), r),
        None => (None, s),
    };
    let parts: Vec<u64> = rest.split(':').map(num).collect::<Result<_, _>>()?;
    let secs = match (days, parts.as_slice()) {
        (None, [m]) => m * 60,
        (None, [m, s]) => m * 60 + s,
        (None, [h, m, s]) => h * 3600 + m * 60 + s,
        (Some(d), [h]) => d * 86400 + h * 3600,
        (Some(d), [h, m]) => d * 86400 + h * 3600 + m * 60,
        (Some(d), [h, m, s]) => d * 86400 + h * 3600 + m * 60 + s,
        _ => return Err(bad("too many parts")),
    };
    if secs == 0 || secs > MAX_TIME_S {
        return Err(bad("out of range"));
    }
    Ok(secs)
}

/// Seconds as Slurm's `DAYS-HH:MM:SS`.
pub(crate) fn slurm_time(secs: u64) -> String {
    let (d, r) = (secs / 86400, secs % 86400);
    format!("{d}-{:02}:{:02}:{:02}", r / 3600, r % 3600 / 60, r % 60)
}

/// A Slurm partition, account or QOS name: 1 to 64 letters, digits, `_`, `-` or `.` (a
/// partition list may hold commas).
pub(crate) fn check_slurm_name(flag: &str, s: &str) -> Result<String, FarmError> {
    let comma_ok = flag == "--partition";
    let ok = !s.is_empty()
        && s.len() <= 64
        && s.bytes().all(|b| {
            b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.') || (comma_ok && b == b',')
        })
        && !s.starts_with('-');
    if !ok {
        return usage(format!(
            "{flag} {s:?}: use 1 to 64 letters, digits, `_`, `-` or `.`{}",
            if comma_ok { " (a list: commas)" } else { "" }
        ));
    }
    Ok(s.to_string())
}

/// The `#SBATCH` options nsrm writes itself, and the flag that sets each.
const SBATCH_OWN: [(&str, &str); 11] = [
    ("array", "--shards"),
    ("job-name", "--name"),
    ("output", "the job (NAME-%A_%a.out)"),
    ("cpus-per-task", "--cpus"),
    ("mem", "--mem"),
    ("time", "--time"),
    ("gpus", "--gpus"),
    ("partition", "--partition"),
    ("account", "--account"),
    ("qos", "--qos"),
    ("dependency", "submit.sh"),
];

/// One extra `#SBATCH` argument: `--name` or `--name=value`, the name lowercase letters,
/// digits and `-`, the value without control characters, quotes or backslashes (Slurm's
/// directive reader knows no escapes); a value with spaces is written double-quoted. The
/// options nsrm sets itself are refused with the flag that sets them.
pub(crate) fn parse_sbatch_arg(s: &str) -> Result<String, FarmError> {
    let Some(body) = s.strip_prefix("--") else {
        return usage(format!(
            "--sbatch-arg {s:?}: give a long option, --name or --name=value (e.g. --sbatch-arg=--constraint=avx2)"
        ));
    };
    let (name, value) = match body.split_once('=') {
        Some((n, v)) => (n, Some(v)),
        None => (body, None),
    };
    if name.is_empty()
        || name.len() > 64
        || !name.starts_with(|c: char| c.is_ascii_lowercase())
        || !name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
    {
        return usage(format!(
            "--sbatch-arg {s:?}: the option's name is lowercase letters, digits and `-`"
        ));
    }
    if let Some((_, flag)) = SBATCH_OWN.iter().find(|(o, _)| *o == name) {
        return usage(format!(
            "--sbatch-arg {s:?}: nsrm writes --{name} itself; set it with {flag}"
        ));
    }
    match value {
        None => Ok(format!("--{name}")),
        Some(v) => {
            if v.len() > 1024 || v.chars().any(|c| c.is_control() || "\"'\\".contains(c)) {
                return usage(format!(
                    "--sbatch-arg {s:?}: a value holds no control character, quote or backslash, and at most 1024 bytes"
                ));
            }
            if v.is_empty() || v.contains(char::is_whitespace) {
                Ok(format!("--{name}=\"{v}\""))
            } else {
                Ok(format!("--{name}={v}"))
            }
        }
    }
}

/// A Kubernetes extended resource name for `--gpu-resource`: `DOMAIN/NAME`, the domain a DNS
/// subdomain outside `kubernetes.io` (at most 253 characters), the name 1 to 63 letters, digits,
/// `-`, `_` or `.` starting and ending with a letter or digit.
pub(crate) fn check_gpu_resource(s: &str) -> Result<String, FarmError> {
    let bad = || {
        usage(format!(
            "--gpu-resource {s:?}: give an extended resource name, DOMAIN/NAME (e.g. nvidia.com/gpu, amd.com/gpu, gpu.intel.com/i915)"
        ))
    };
    let Some((domain, name)) = s.split_once('/') else {
        return bad();
    };
    let domain_ok = domain.len() <= 253
        && domain.contains('.')
        && domain.split('.').all(|l| is_dns_label(l, 63))
        && !domain.ends_with("kubernetes.io");
    let name_ok = !name.is_empty()
        && name.len() <= 63
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
        && name.starts_with(|c: char| c.is_ascii_alphanumeric())
        && name.ends_with(|c: char| c.is_ascii_alphanumeric());
    if !(domain_ok && name_ok) {
        return bad();
    }
    Ok(s.to_string())
}

/// The pod-spec fields nsrm writes itself, and the flag that sets each.
const POD_SPEC_OWN: [(&str, &str); 6] = [
    ("containers", "the job (one container running nsrm)"),
    ("volumes", "--claim"),
    (
        "restartPolicy",
        "the job (Never: a failed shard is retried as a new pod)",
    ),
    ("nodeSelector", "--node-selector"),
    ("tolerations", "--toleration"),
    ("activeDeadlineSeconds", "--time and --verify-time"),
];

/// The `--pod-spec FIELD=JSON` values as pod-spec fields: FIELD a camelCase name (letters and
/// digits, at most 64) given once and not one nsrm writes, JSON a value of at most
/// [`MAX_POD_FIELD_BYTES`] (strings, whole numbers, booleans, lists and objects; a fraction or
/// `null` is refused: no pod-spec field takes one).
pub(crate) fn parse_pod_fields(
    args: &[String],
) -> Result<Vec<(String, serde_json::Value)>, FarmError> {
    let mut out: Vec<(String, serde_json::Value)> = Vec::new();
    for a in args {
        let Some((field, json)) = a.split_once('=') else {
            return usage(format!(
                "--pod-spec {a:?}: give FIELD=JSON (e.g. --pod-spec priorityClassName='\"render\"')"
            ));
        };
        if field.is_empty()
            || field.len() > 64
            || !field.starts_with(|c: char| c.is_ascii_lowercase())
            || !field.bytes().all(|b| b.is_ascii_alphanumeric())
        {
            return usage(format!(
                "--pod-spec {a:?}: the field is a pod-spec field name in camelCase (letters and digits)"
            ));
        }
        if let Some((_, flag)) = POD_SPEC_OWN.iter().find(|(o, _)| *o == field) {
            return usage(format!(
                "--pod-spec {a:?}: nsrm writes {field} itself; set it with {flag}"
            ));
        }
        if out.iter().any(|(k, _)| k == field) {
            return usage(format!("--pod-spec {a:?}: {field} is given twice"));
        }
        if json.len() > MAX_POD_FIELD_BYTES {
            return usage(format!(
                "--pod-spec {field}: the value is over {} KiB",
                MAX_POD_FIELD_BYTES >> 10
            ));
        }
        let value: serde_json::Value = serde_json::from_str(json).map_err(|e| {
            FarmError::Usage(format!(
                "--pod-spec {field}: the value is not JSON ({e}); a string is quoted, e.g. '\"render\"'"
            ))
        })?;
        check_pod_value(&value)
            .map_err(|why| FarmError::Usage(format!("--pod-spec {field}: {why}")))?;
        out.push((field.to_string(), value));
    }
    Ok(out)
}

/// Refuses what no pod-spec field takes: `null` and fractions, anywhere in a value (serde_json
/// bounds the nesting it parses; an object's keys are written sorted).
fn check_pod_value(v: &serde_json::Value) -> Result<(), String> {
    use serde_json::Value;
    match v {
        Value::Null => Err("null is not a pod-spec value (leave the field out)".into()),
        Value::Number(n) if n.as_i64().is_none() => Err(format!(
            "{n}: pod-spec numbers are whole (a quantity such as \"1.5\" is a string)"
        )),
        Value::Array(a) => a.iter().try_for_each(check_pod_value),
        Value::Object(o) => o.values().try_for_each(check_pod_value),
        _ => Ok(()),
    }
}

/// An RFC 1123 DNS label: 1 to `max` (at most 63) lowercase letters, digits and `-`, starting
/// and ending with a letter or digit.
pub(crate) fn is_dns_label(s: &str, max: usize) -> bool {
    !s.is_empty()
        && s.len() <= max.min(63)
        && s.bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
        && !s.starts_with('-')
        && !s.ends_with('-')
}

/// The longest Kubernetes job name: a DNS label of 63 less `-verify`, the longest suffix nsrm
/// gives the batch's objects.
pub(crate) const KUBE_MAX_NAME: usize = 63 - "-verify".len();

/// Refuses a Kubernetes object name that is not an RFC 1123 DNS label of at most
/// [`KUBE_MAX_NAME`] characters (the Job, its pods' label and the `-inputs`/`-verify`
/// objects are named from it).
pub(crate) fn check_kube_name(name: &str) -> Result<(), FarmError> {
    if is_dns_label(name, KUBE_MAX_NAME) {
        return Ok(());
    }
    usage(format!(
        "--name {name:?}: a Kubernetes job name must be an RFC 1123 DNS label: lowercase letters, digits and `-`, starting and ending with a letter or digit, at most {KUBE_MAX_NAME} characters (63 less `-verify`)"
    ))
}

/// A label value: empty, or up to 63 letters, digits, `-`, `_`, `.`, starting and ending
/// with a letter or digit.
fn is_label_value(s: &str) -> bool {
    s.is_empty()
        || (s.len() <= 63
            && s.bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
            && s.starts_with(|c: char| c.is_ascii_alphanumeric())
            && s.ends_with(|c: char| c.is_ascii_alphanumeric()))
}

/// A label (or taint) key: `[PREFIX/]NAME`, the prefix a DNS subdomain (at most 253
/// characters), the name a non-empty label value.
fn is_label_key(s: &str) -> bool {
    let (prefix, name) = match s.rsplit_once('/') {
        Some((p, n)) => (Some(p), n),
        None => (None, s),
    };
    let prefix_ok =
        prefix.is_none_or(|p| p.len() <= 253 && p.split('.').all(|l| is_dns_label(l, 63)));
    prefix_ok && !name.is_empty() && is_label_value(name)
}

/// `--node-selector KEY=VALUE`.
pub(crate) fn parse_node_selector(s: &str) -> Result<(String, String), FarmError> {
    match s.split_once('=') {
        Some((k, v)) if is_label_key(k) && is_label_value(v) => Ok((k.into(), v.into())),
        _ => usage(format!(
            "--node-selector {s:?}: give KEY=VALUE, a Kubernetes label: KEY is [PREFIX/]NAME (NAME up to 63 letters, digits, `-`, `_`, `.`; PREFIX a DNS subdomain), VALUE up to 63 of the same characters"
        )),
    }
}

const TAINT_EFFECTS: [&str; 3] = ["NoSchedule", "PreferNoSchedule", "NoExecute"];

/// `--toleration KEY[=VALUE][:EFFECT]`.
pub(crate) fn parse_toleration(s: &str) -> Result<Toleration, FarmError> {
    let bad = || {
        FarmError::Usage(format!(
            "--toleration {s:?}: give KEY[=VALUE][:EFFECT] as `kubectl taint` writes a taint (KEY and VALUE are label names; EFFECT is {}; without VALUE any value is tolerated, without EFFECT every effect)",
            TAINT_EFFECTS.join(", ")
        ))
    };
    let (kv, effect) = match s.rsplit_once(':') {
        Some((kv, e)) if TAINT_EFFECTS.contains(&e) => (kv, Some(e.to_string())),
        Some(_) => return Err(bad()),
        None => (s, None),
    };
    let (key, value) = match kv.split_once('=') {
        Some((k, v)) => (k, Some(v)),
        None => (kv, None),
    };
    if !is_label_key(key) || value.is_some_and(|v| !is_label_value(v)) {
        return Err(bad());
    }
    Ok(Toleration {
        key: key.into(),
        value: value.map(str::to_string),
        effect,
    })
}

/// The OS families Open Job Description names.
const OS_FAMILIES: [&str; 3] = ["linux", "windows", "macos"];

pub(crate) fn check_os_family(s: &str) -> Result<String, FarmError> {
    let l = s.to_ascii_lowercase();
    if OS_FAMILIES.contains(&l.as_str()) {
        Ok(l)
    } else {
        usage(format!(
            "--os-family {s:?}: Open Job Description names {}",
            OS_FAMILIES.join(", ")
        ))
    }
}

/// The host requirements nsrm writes itself, and the flag that sets each.
const OPENJD_OWN: [(&str, &str); 4] = [
    ("amount.worker.vcpu", "--cpus"),
    ("amount.worker.memory", "--mem"),
    ("amount.worker.gpu", "--gpus"),
    ("attr.worker.os.family", "--os-family"),
];

/// An Open Job Description capability name (as its model checks one): `[VENDOR:]amount.…` or
/// `[VENDOR:]attr.…`, lowercase dot-separated words; the `worker`, `job`, `step` and `task`
/// scopes are the standard names only.
fn is_capability_name(s: &str, kind: &str) -> bool {
    const STANDARD: [&str; 7] = [
        "amount.worker.vcpu",
        "amount.worker.memory",
        "amount.worker.gpu",
        "amount.worker.gpu.memory",
        "amount.worker.disk.scratch",
        "attr.worker.os.family",
        "attr.worker.cpu.arch",
    ];
    if s.len() > 100 {
        return false;
    }
    let word = |w: &str| {
        !w.is_empty()
            && w.starts_with(|c: char| c.is_ascii_lowercase() || c == '_')
            && w.bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
    };
    let (vendor, rest) = match s.split_once(':') {
        Some((v, r)) => (Some(v), r),
        None => (None, s),
    };
    if vendor.is_some_and(|v| !word(v) || v.len() < 2) {
        return false;
    }
    let words: Vec<&str> = rest.split('.').collect();
    if words.len() < 2 || words[0] != kind || !words.iter().all(|w| word(w)) {
        return false;
    }
    vendor.is_some()
        || STANDARD.contains(&rest)
        || !["worker", "job", "step", "task"].contains(&words[1])
}

/// `--host-requirement NAME=VALUE`: `amount.…=N` (a number ≥ 0: at least N) or
/// `attr.…=V[,V…]` (any of the values: letters, digits, `_`, `-`).
pub(crate) fn parse_host_requirement(s: &str) -> Result<HostRequirement, FarmError> {
    let bad = |why: &str| {
        FarmError::Usage(format!(
            "--host-requirement {s:?}: {why} (NAME=VALUE: amount.NAME=N for at least N, attr.NAME=V1,V2 for any of the values; names as Open Job Description's capabilities)"
        ))
    };
    let Some((name, value)) = s.split_once('=') else {
        return Err(bad("no `=`"));
    };
    let name = name.to_ascii_lowercase();
    if let Some((_, flag)) = OPENJD_OWN.iter().find(|(o, _)| *o == name) {
        return Err(bad(&format!(
            "nsrm writes {name} itself; set it with {flag}"
        )));
    }
    if is_capability_name(&name, "amount") {
        let min: f64 = value
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0 && *v <= 1e12)
            .ok_or_else(|| bad("an amount is a number from 0 to 1e12"))?;
        return Ok(HostRequirement::Amount { name, min });
    }
    if is_capability_name(&name, "attr") {
        let any_of: Vec<String> = value.split(',').map(str::to_string).collect();
        let ok = any_of.len() <= 50
            && any_of.iter().all(|v| {
                !v.is_empty()
                    && v.len() <= 100
                    && v.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
                    && v.bytes()
                        .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
            });
        if !ok {
            return Err(bad(
                "attribute values are 1 to 50 words of letters, digits, `_` and `-`",
            ));
        }
        return Ok(HostRequirement::Attr { name, any_of });
    }
    Err(bad("not an amount.… or attr.… capability name"))
}

/// What a task's memory default is made of: `(jobs + 2)` frames alive at once (the decoders'
/// and encoders' `--jobs`, the one being corrected, the one queued: `apply`'s bound), each of
/// `frame_bytes`, plus the program's own, with a quarter more as headroom.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct MemEstimate {
    pub jobs: u32,
    pub frame_bytes: u64,
    pub mib: u64,
}

/// The program's own memory besides its frames (code, the model, the GPU driver's), in MiB.
pub(crate) const BASE_MIB: u64 = 256;

/// Bytes a decoded frame of `pixels` occupies while it is converted: the camera RGB as f32
/// (12 bytes a pixel) and the file's other channels (alpha, passes) as stored
/// (`other_bytes_per_pixel`), which the writer passes through.
pub(crate) fn frame_bytes(pixels: u64, other_bytes_per_pixel: u64) -> u64 {
    pixels.saturating_mul(12 + other_bytes_per_pixel)
}

/// The memory default of a task running `jobs` workers on frames of at most `frame_bytes`.
pub(crate) fn estimate_mem(jobs: u32, frame_bytes: u64) -> MemEstimate {
    let frames = u64::from(jobs) + 2;
    let bytes = frames.saturating_mul(frame_bytes);
    let mib = (BASE_MIB + bytes.div_ceil(1 << 20)).saturating_mul(5) / 4;
    MemEstimate {
        jobs,
        frame_bytes,
        mib: mib.clamp(MIN_MEM_MIB, MAX_MEM_MIB),
    }
}

/// MiB as a short text (`512 MiB`, `3.5 GiB`).
pub(crate) fn mib_text(mib: u64) -> String {
    if mib >= 1024 {
        format!("{:.1} GiB", mib as f64 / 1024.0)
    } else {
        format!("{mib} MiB")
    }
}

/// An Open Job Description amount's minimum: whole numbers as integers, others as the
/// decimal text (`"1.5"`), which the specification's decimal fields take exactly.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub(crate) enum AmountMin {
    Int(i64),
    Text(String),
}

impl AmountMin {
    fn of(v: f64) -> AmountMin {
        if v.fract() == 0.0 && v.abs() < 9e15 {
            AmountMin::Int(v as i64)
        } else {
            AmountMin::Text(format!("{v}"))
        }
    }
}

/// An Open Job Description step's `hostRequirements`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct HostRequirements<'a> {
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub amounts: Vec<AmountRequirement<'a>>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub attributes: Vec<AttributeRequirement<'a>>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct AmountRequirement<'a> {
    pub name: &'a str,
    pub min: AmountMin,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub(crate) struct AttributeRequirement<'a> {
    pub name: &'a str,
    pub any_of: Vec<&'a str>,
}

/// A container's `resources`: quantities by resource name, in the order written.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct KubeResources<'a> {
    #[serde(skip_serializing_if = "Pairs::is_empty")]
    pub requests: Pairs<&'a str, String>,
    #[serde(skip_serializing_if = "Pairs::is_empty")]
    pub limits: Pairs<&'a str, String>,
}

/// A pod spec's scheduling fields and the `--pod-spec` pass-through (flattened into the pod
/// spec after its own fields).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub(crate) struct KubeScheduling<'a> {
    #[serde(skip_serializing_if = "Pairs::is_empty")]
    pub node_selector: Pairs<&'a str, &'a str>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tolerations: Vec<KubeToleration<'a>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub active_deadline_seconds: Option<u64>,
    #[serde(flatten)]
    pub pod_fields: Pairs<&'a str, &'a serde_json::Value>,
}

/// A toleration as a pod spec holds it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub(crate) struct KubeToleration<'a> {
    pub key: &'a str,
    pub operator: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub effect: Option<&'a str>,
}

impl Resources {
    /// The one line `nsrm farm` prints of what each task asks for.
    pub(crate) fn summary(&self) -> String {
        let mut parts = vec![
            match self.cpus {
                Some(c) => format!("{c} CPU(s)"),
                None => "CPUs: engine default".into(),
            },
            match self.mem_mib {
                Some(m) => format!("{} memory", mib_text(m)),
                None => "memory: engine default".into(),
            },
            format!("{} GPU(s)", self.gpus),
            match self.time_s {
                Some(t) => format!("time limit {}", slurm_time(t)),
                None => "no time limit (engine default)".into(),
            },
        ];
        if let Some(t) = self.verify_time_s {
            parts.push(format!("verification time limit {}", slurm_time(t)));
        }
        if self.gpus > 0 {
            if let Some(g) = &self.gpu_resource {
                parts.push(format!("GPUs as {g}"));
            }
        }
        for (what, v) in [
            ("partition", &self.partition),
            ("account", &self.account),
            ("qos", &self.qos),
            ("os family", &self.os_family),
        ] {
            if let Some(v) = v {
                parts.push(format!("{what} {v}"));
            }
        }
        parts.join(", ")
    }

    /// The `#SBATCH` lines of a task (`task`) or of the verification: partition, account,
    /// QOS and the pass-through for both; CPUs, memory, GPUs and time as given for a task, one
    /// CPU, the task's memory and `--verify-time` (else the partition's limit) for the
    /// verification.
    pub(crate) fn sbatch_lines(&self, task: bool) -> String {
        let mut lines = Vec::new();
        let mut push = |s: String| lines.push(format!("#SBATCH {s}\n"));
        if let Some(p) = &self.partition {
            push(format!("--partition={p}"));
        }
        if let Some(a) = &self.account {
            push(format!("--account={a}"));
        }
        if let Some(q) = &self.qos {
            push(format!("--qos={q}"));
        }
        let cpus = if task {
            self.cpus
        } else {
            self.cpus.map(|_| 1)
        };
        if let Some(c) = cpus {
            push(format!("--cpus-per-task={c}"));
        }
        if let Some(m) = self.mem_mib {
            push(format!("--mem={m}M"));
        }
        if task && self.gpus > 0 {
            push(format!("--gpus={}", self.gpus));
        }
        if let Some(t) = if task {
            self.time_s
        } else {
            self.verify_time_s
        } {
            push(format!("--time={}", slurm_time(t)));
        }
        for a in &self.sbatch_args {
            push(a.clone());
        }
        lines.concat()
    }

    /// An Open Job Description step's `hostRequirements` (`task`: the Apply step's, with the
    /// GPUs; else the Verify step's, one vCPU), or `None` when nothing is asked.
    pub(crate) fn openjd_host_requirements(&self, task: bool) -> Option<HostRequirements<'_>> {
        let amount = |name, min: u64| AmountRequirement {
            name,
            min: AmountMin::Int(min as i64),
        };
        let mut amounts = Vec::new();
        let cpus = if task {
            self.cpus
        } else {
            self.cpus.map(|_| 1)
        };
        if let Some(c) = cpus {
            amounts.push(amount("amount.worker.vcpu", c.into()));
        }
        if let Some(m) = self.mem_mib {
            amounts.push(amount("amount.worker.memory", m));
        }
        if task && self.gpus > 0 {
            amounts.push(amount("amount.worker.gpu", self.gpus.into()));
        }
        let mut attributes = Vec::new();
        if let Some(os) = &self.os_family {
            attributes.push(AttributeRequirement {
                name: "attr.worker.os.family",
                any_of: vec![os.as_str()],
            });
        }
        for r in &self.host_requirements {
            match r {
                HostRequirement::Amount { name, min } => amounts.push(AmountRequirement {
                    name,
                    min: AmountMin::of(*min),
                }),
                HostRequirement::Attr { name, any_of } => attributes.push(AttributeRequirement {
                    name,
                    any_of: any_of.iter().map(String::as_str).collect(),
                }),
            }
        }
        (!amounts.is_empty() || !attributes.is_empty()).then_some(HostRequirements {
            amounts,
            attributes,
        })
    }

    /// A container's `resources` (`task`: with the GPUs): requests of CPUs and memory, a
    /// memory limit equal to the request (a pod over it is killed, not the node), GPUs as
    /// limits (`--gpu-resource`, `nvidia.com/gpu` by default). `None` when nothing is asked.
    pub(crate) fn kube_resources(&self, task: bool) -> Option<KubeResources<'_>> {
        let mut requests = Vec::new();
        let mut limits = Vec::new();
        let cpus = if task {
            self.cpus
        } else {
            self.cpus.map(|_| 1)
        };
        if let Some(c) = cpus {
            requests.push(("cpu", c.to_string()));
        }
        if let Some(m) = self.mem_mib {
            requests.push(("memory", format!("{m}Mi")));
            limits.push(("memory", format!("{m}Mi")));
        }
        if task && self.gpus > 0 {
            let name = self.gpu_resource.as_deref().unwrap_or(KUBE_GPU);
            limits.push((name, self.gpus.to_string()));
        }
        (!requests.is_empty() || !limits.is_empty()).then_some(KubeResources {
            requests: Pairs(requests),
            limits: Pairs(limits),
        })
    }

    /// A pod spec's scheduling fields: `nodeSelector`, `tolerations`, `activeDeadlineSeconds`
    /// (a task's `--time`: each pod, so each try of a shard, is stopped after it; the
    /// verification's `--verify-time`), then the `--pod-spec` pass-through.
    pub(crate) fn kube_pod_fields(&self, task: bool) -> KubeScheduling<'_> {
        KubeScheduling {
            node_selector: Pairs(
                self.node_selector
                    .iter()
                    .map(|(k, v)| (k.as_str(), v.as_str()))
                    .collect(),
            ),
            tolerations: self
                .tolerations
                .iter()
                .map(|t| KubeToleration {
                    key: &t.key,
                    operator: if t.value.is_some() { "Equal" } else { "Exists" },
                    value: t.value.as_deref(),
                    effect: t.effect.as_deref(),
                })
                .collect(),
            active_deadline_seconds: if task {
                self.time_s
            } else {
                self.verify_time_s
            },
            pod_fields: Pairs(
                self.pod_fields
                    .iter()
                    .map(|(k, v)| (k.as_str(), v))
                    .collect(),
            ),
        }
    }
}

/// The resource flags of `nsrm farm openjd|slurm|k8s`, one group for every engine (each
/// engine writes what it knows and says nothing of the rest).
#[derive(Debug, Clone, Default, clap::Args)]
#[command(next_help_heading = "Resources of each task")]
pub(crate) struct ResourceArgs {
    /// CPUs per task (Slurm --cpus-per-task, Kubernetes cpu request, Open Job Description
    /// amount.worker.vcpu); default apply's --jobs, else 4. A task runs --jobs workers: as
    /// many as its CPUs unless --jobs says otherwise.
    #[arg(long, value_name = "N")]
    pub cpus: Option<u32>,
    /// Memory per task: a whole number with K, M, G or T (powers of 1024), e.g. 8G (Slurm
    /// --mem, Kubernetes memory request and limit, amount.worker.memory); default from the
    /// batch: (jobs + 2) of its largest frame, plus 256 MiB, plus a quarter.
    #[arg(long, value_name = "SIZE")]
    pub mem: Option<String>,
    /// Wall-time limit per task in Slurm's syntax (MINUTES, HH:MM:SS, D-HH:MM:SS…): Slurm
    /// --time, Kubernetes activeDeadlineSeconds of each pod, the Open Job Description
    /// action's timeout; default none (the engine's).
    #[arg(long, value_name = "TIME")]
    pub time: Option<String>,
    /// Wall-time limit of the verification job or step (it reads every output once), in
    /// --time's syntax; default none (the engine's).
    #[arg(long = "verify-time", value_name = "TIME")]
    pub verify_time: Option<String>,
    /// GPUs per task (Slurm --gpus, Kubernetes nvidia.com/gpu limit, amount.worker.gpu);
    /// default 1 with --device gpu, else 0.
    #[arg(long, value_name = "N")]
    pub gpus: Option<u32>,
    /// Slurm partition (or a comma-separated list).
    #[arg(long, value_name = "NAME")]
    pub partition: Option<String>,
    /// Slurm account charged.
    #[arg(long, value_name = "NAME")]
    pub account: Option<String>,
    /// Slurm quality of service.
    #[arg(long, value_name = "NAME")]
    pub qos: Option<String>,
    /// An extra #SBATCH line for both Slurm scripts, as a long option: --name or --name=value
    /// (e.g. --sbatch-arg=--constraint=avx2); repeatable. Quotes, backslashes and control
    /// characters are refused; a value with spaces is double-quoted.
    #[arg(long = "sbatch-arg", value_name = "OPTION", allow_hyphen_values = true)]
    pub sbatch_arg: Vec<String>,
    /// Kubernetes node selector KEY=VALUE (a node label); repeatable.
    #[arg(long = "node-selector", value_name = "KEY=VALUE")]
    pub node_selector: Vec<String>,
    /// Kubernetes toleration KEY[=VALUE][:EFFECT], as `kubectl taint` writes a taint: with
    /// VALUE the operator is Equal, without it Exists; EFFECT NoSchedule, PreferNoSchedule
    /// or NoExecute, without it every effect; repeatable.
    #[arg(long, value_name = "TAINT")]
    pub toleration: Vec<String>,
    /// The Kubernetes extended resource a GPU is asked for as (e.g. amd.com/gpu,
    /// gpu.intel.com/i915); default nvidia.com/gpu.
    #[arg(long = "gpu-resource", value_name = "NAME")]
    pub gpu_resource: Option<String>,
    /// A further field of every Kubernetes pod spec, FIELD=JSON (e.g.
    /// priorityClassName='"render"', runtimeClassName='"nvidia"',
    /// securityContext='{"runAsUser":1000}'); the fields nsrm writes itself are refused with
    /// the flag that sets them; repeatable.
    #[arg(long = "pod-spec", value_name = "FIELD=JSON")]
    pub pod_spec: Vec<String>,
    /// Open Job Description attr.worker.os.family: linux, windows or macos; default any.
    #[arg(long, value_name = "FAMILY")]
    pub os_family: Option<String>,
    /// A further Open Job Description host requirement: amount.NAME=N (at least N) or
    /// attr.NAME=V1,V2 (any of the values), e.g. attr.worker.cpu.arch=x86_64; repeatable.
    #[arg(long = "host-requirement", value_name = "NAME=VALUE")]
    pub host_requirement: Vec<String>,
}

/// What the defaults of a batch are derived from.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BatchFacts<'a> {
    /// apply's `--jobs`, when given.
    pub jobs: Option<u32>,
    /// Whether apply's `--device` is `gpu`.
    pub device_gpu: bool,
    /// The largest frame found, when a header could be read.
    pub frame: Option<&'a FrameProbe>,
}

/// CPUs a task asks for when neither --cpus nor --jobs says.
pub(crate) const DEFAULT_CPUS: u32 = 4;

/// Refuses more than [`MAX_REPEATS`] values of a repeatable flag.
fn check_repeats(flag: &str, n: usize) -> Result<(), FarmError> {
    if n > MAX_REPEATS {
        return usage(format!("{flag}: at most {MAX_REPEATS} of them"));
    }
    Ok(())
}

impl ResourceArgs {
    /// The checked resources, the defaults filled from `facts`; with them, how the memory
    /// default was found (`None` when --mem was given).
    pub(crate) fn resolve(
        &self,
        facts: BatchFacts<'_>,
    ) -> Result<(Resources, Option<String>), FarmError> {
        let cpus = match self.cpus {
            Some(c) => check_count("--cpus", c, false)?,
            None => facts.jobs.unwrap_or(DEFAULT_CPUS).clamp(1, MAX_COUNT),
        };
        let gpus = match self.gpus {
            Some(g) => check_count("--gpus", g, true)?,
            None => u32::from(facts.device_gpu),
        };
        let jobs = facts.jobs.unwrap_or(cpus).max(1);
        let (mem_mib, how) = match &self.mem {
            Some(m) => (parse_mem(m)?, None),
            None => match facts.frame {
                Some(f) => {
                    let e = estimate_mem(jobs, f.bytes);
                    let how = format!(
                        "memory from the batch: ({jobs} jobs + 2) × {} frame of {}×{} (largest of {} header(s) read{}) + {BASE_MIB} MiB, + 25%",
                        mib_text(f.bytes.div_ceil(1 << 20)),
                        f.width,
                        f.height,
                        f.probed - f.unread,
                        if f.unread > 0 {
                            format!(", {} unreadable", f.unread)
                        } else {
                            String::new()
                        }
                    );
                    (e.mib, Some(how))
                }
                None => {
                    let mib = (BASE_MIB * 4).max(MIN_MEM_MIB);
                    (
                        mib,
                        Some(format!(
                            "memory: no input's header could be read, so {} (set --mem)",
                            mib_text(mib)
                        )),
                    )
                }
            },
        };
        check_repeats("--sbatch-arg", self.sbatch_arg.len())?;
        check_repeats("--node-selector", self.node_selector.len())?;
        check_repeats("--toleration", self.toleration.len())?;
        check_repeats("--pod-spec", self.pod_spec.len())?;
        check_repeats("--host-requirement", self.host_requirement.len())?;
        Ok((
            Resources {
                cpus: Some(cpus),
                mem_mib: Some(mem_mib),
                time_s: self.time.as_deref().map(parse_time).transpose()?,
                verify_time_s: self
                    .verify_time
                    .as_deref()
                    .map(|t| parse_time_for("--verify-time", t))
                    .transpose()?,
                gpus,
                gpu_resource: self
                    .gpu_resource
                    .as_deref()
                    .map(check_gpu_resource)
                    .transpose()?,
                pod_fields: parse_pod_fields(&self.pod_spec)?,
                partition: self
                    .partition
                    .as_deref()
                    .map(|p| check_slurm_name("--partition", p))
                    .transpose()?,
                account: self
                    .account
                    .as_deref()
                    .map(|p| check_slurm_name("--account", p))
                    .transpose()?,
                qos: self
                    .qos
                    .as_deref()
                    .map(|p| check_slurm_name("--qos", p))
                    .transpose()?,
                sbatch_args: self
                    .sbatch_arg
                    .iter()
                    .map(|a| parse_sbatch_arg(a))
                    .collect::<Result<_, _>>()?,
                node_selector: self
                    .node_selector
                    .iter()
                    .map(|a| parse_node_selector(a))
                    .collect::<Result<_, _>>()?,
                tolerations: self
                    .toleration
                    .iter()
                    .map(|a| parse_toleration(a))
                    .collect::<Result<_, _>>()?,
                os_family: self.os_family.as_deref().map(check_os_family).transpose()?,
                host_requirements: self
                    .host_requirement
                    .iter()
                    .map(|a| parse_host_requirement(a))
                    .collect::<Result<_, _>>()?,
            },
            how,
        ))
    }

    /// The flags given that `engine` (`openjd`, `slurm`, `k8s`) has no place for.
    pub(crate) fn foreign(&self, engine: &str) -> Vec<&'static str> {
        let mut v = Vec::new();
        if engine != "slurm" {
            for (set, f) in [
                (self.partition.is_some(), "--partition"),
                (self.account.is_some(), "--account"),
                (self.qos.is_some(), "--qos"),
                (!self.sbatch_arg.is_empty(), "--sbatch-arg"),
            ] {
                if set {
                    v.push(f);
                }
            }
        }
        if engine != "k8s" {
            for (set, f) in [
                (!self.node_selector.is_empty(), "--node-selector"),
                (!self.toleration.is_empty(), "--toleration"),
                (self.gpu_resource.is_some(), "--gpu-resource"),
                (!self.pod_spec.is_empty(), "--pod-spec"),
            ] {
                if set {
                    v.push(f);
                }
            }
        }
        if engine != "openjd" {
            for (set, f) in [
                (self.os_family.is_some(), "--os-family"),
                (!self.host_requirement.is_empty(), "--host-requirement"),
            ] {
                if set {
                    v.push(f);
                }
            }
        }
        v
    }
}

/// Headers read at most for the memory default.
const MAX_PROBED: usize = 16;

/// The resources of a batch whose apply settings are `settings` and whose inputs are
/// `inputs` (as the submitter names them): the defaults from `--jobs`, `--device` and the
/// largest frame found, printed in one line. Without `--jobs`, the tasks run as many workers
/// as the CPUs asked for (`--jobs=N` is added to `settings`): a pod sees all of its node's
/// CPUs, and the memory asked for is sized by the workers.
pub(crate) fn resolve(
    args: &ResourceArgs,
    settings: &mut Vec<String>,
    inputs: &[std::path::PathBuf],
) -> Result<Resources, FarmError> {
    let jobs = settings
        .iter()
        .find_map(|w| w.strip_prefix("--jobs="))
        .and_then(|j| j.parse::<u32>().ok());
    let device_gpu = settings
        .windows(2)
        .any(|w| w[0] == "--device" && w[1] == "gpu");
    let probe = if args.mem.is_none() {
        probe_frames(inputs, MAX_PROBED)
    } else {
        None
    };
    let (r, how) = args.resolve(BatchFacts {
        jobs,
        device_gpu,
        frame: probe.as_ref(),
    })?;
    let mut line = format!("nsrm farm: each task asks for {}", r.summary());
    if let Some(h) = how {
        line.push_str(&format!("; {h}"));
    }
    if jobs.is_none() {
        let cpus = r.cpus.unwrap_or(DEFAULT_CPUS);
        settings.push(format!("--jobs={cpus}"));
        line.push_str(&format!("; apply runs --jobs {cpus} (one worker a CPU)"));
    }
    eprintln!("{line}");
    Ok(r)
}

/// Whether `path` is `dir` or under it, whole components only.
fn is_under(path: &str, dir: &str) -> bool {
    let dir = dir.trim_end_matches('/');
    dir.is_empty() || path == dir || path.strip_prefix(dir).is_some_and(|r| r.starts_with('/'))
}

/// A warning naming the `paths` (as the pods will see them, after --path-map) that are not
/// under the claim's mount `mount`, with the fix; `None` when all are.
pub(crate) fn outside_mount(mount: &str, paths: &[&str]) -> Option<String> {
    let outside: Vec<&str> = paths
        .iter()
        .copied()
        .filter(|p| !is_under(p, mount))
        .collect();
    let first = outside.first()?;
    let shown: Vec<&str> = outside.iter().take(3).copied().collect();
    let more = outside.len() - shown.len();
    let parent = std::path::Path::new(first)
        .parent()
        .and_then(|p| p.to_str())
        .filter(|p| !p.is_empty() && *p != "/")
        .unwrap_or(first);
    Some(format!(
        "nsrm farm: warning: {} path(s) of the job are not under the claim's mount {mount}, so the pods will not find them: {}{}; map them onto the claim, e.g. --path-map {parent}={}/…",
        outside.len(),
        shown.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        },
        mount.trim_end_matches('/')
    ))
}

/// The largest frame of a batch as far as its headers tell, from at most `max_probed` inputs
/// spread over the list (first and last included): pixels, channels and the bytes a decoded
/// frame of it occupies ([`frame_bytes`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct FrameProbe {
    pub width: u64,
    pub height: u64,
    pub bytes: u64,
    pub probed: usize,
    /// Inputs whose header could not be read (a camera raw file, a broken one).
    pub unread: usize,
}

/// Reads the headers of up to `max_probed` of `inputs` (EXR and TIFF; other files are counted
/// as unread) and returns the largest frame; `None` when no header could be read.
pub(crate) fn probe_frames(inputs: &[std::path::PathBuf], max_probed: usize) -> Option<FrameProbe> {
    let n = inputs.len();
    let k = n.min(max_probed.max(1));
    let picks: Vec<usize> = if k <= 1 {
        vec![0]
    } else {
        let mut v: Vec<usize> = (0..k).map(|i| i * (n - 1) / (k - 1)).collect();
        v.dedup();
        v
    };
    let mut best: Option<FrameProbe> = None;
    let mut unread = 0;
    for &i in picks.iter().filter(|&&i| i < n) {
        match nsrm_io::header_size(&inputs[i]) {
            Some(nsrm_io::HeaderSize {
                width: w,
                height: h,
                extra_bytes_per_pixel: stored,
            }) => {
                let bytes = frame_bytes(w.saturating_mul(h), stored);
                if best.as_ref().is_none_or(|b| bytes > b.bytes) {
                    best = Some(FrameProbe {
                        width: w,
                        height: h,
                        bytes,
                        probed: 0,
                        unread: 0,
                    });
                }
            }
            None => unread += 1,
        }
    }
    best.map(|b| FrameProbe {
        probed: picks.len(),
        unread,
        ..b
    })
}

#[cfg(test)]
#[path = "resources_tests.rs"]
mod tests;
