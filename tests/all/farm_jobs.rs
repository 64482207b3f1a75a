//! `nsrm farm openjd|slurm|k8s` as a wrangler submits them: the resources named once reach
//! every engine's file (and are judged by the engines' own checkers: `openjd check`, the
//! Kubernetes API schema through PyPI `kubernetes-validate`, `bash -n` and the `#SBATCH`
//! directives as Slurm reads them); hostile values are refused before anything is written;
//! Kubernetes names, labels and the claim-mount warning; a farm task's log (stderr not a
//! terminal) starts with its header and shows a line per frame.

use crate::common::{assert_ok, nsrm_in, nsrm_ok, stderr, tempdir};
use crate::farm::{batch, have};
use std::path::Path;
use std::process::Command;

/// The documents of a multi-document YAML file.
fn yaml_docs(path: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(path).unwrap();
    serde_norway::Deserializer::from_str(&text)
        .map(|d| serde::Deserialize::deserialize(d).unwrap())
        .collect()
}

/// The job `engine` makes of the batch in `dir` with `extra` flags; its stderr.
fn make(dir: &Path, engine: &str, job: &str, extra: &[&str]) -> String {
    let mut args = vec!["farm", engine, "--shards", "2", "--job-dir", job];
    if engine == "k8s" {
        args.extend(["--image", "nsrm:1", "--claim", "plates"]);
    }
    args.extend(extra);
    args.extend(["--device", "cpu", "--model", "m.json", "-o", "out", "in"]);
    stderr(&nsrm_ok(dir, &args))
}

/// Slurm reads `#SBATCH` lines only before the script's first command; each must be one
/// option Slurm knows the form of (`--name=value`, `--name`, `-X value`) with no quote left
/// open. Returns the directives' options.
fn sbatch_directives(script: &str) -> Vec<String> {
    let mut seen_command = false;
    let mut out = Vec::new();
    for line in script.lines().skip(1) {
        let t = line.trim();
        if let Some(rest) = t.strip_prefix("#SBATCH ") {
            assert!(
                !seen_command,
                "#SBATCH after the first command: {line}\n{script}"
            );
            let ok = rest.starts_with("--")
                && rest[2..]
                    .split('=')
                    .next()
                    .is_some_and(|n| n.bytes().all(|b| b.is_ascii_lowercase() || b == b'-'))
                || (rest.len() > 3 && rest.as_bytes()[0] == b'-' && rest.as_bytes()[2] == b' ');
            assert!(ok, "not an option: {line}");
            assert_eq!(rest.matches('"').count() % 2, 0, "{line}");
            assert!(!rest.contains('\''), "{line}");
            out.push(rest.to_string());
        } else if !(t.is_empty() || t.starts_with('#')) {
            seen_command = true;
        }
    }
    out
}

/// `bash -n` parses a script.
fn bash_parses(path: &Path) {
    let o = Command::new("bash").arg("-n").arg(path).output().unwrap();
    assert_ok(&o);
}

/// The resource flags, named once, reach each engine's file; defaults come from the batch and
/// are printed in one line.
#[test]
fn resources_reach_every_engine() {
    let dir = tempdir("farm-res");
    batch(&dir, 3, 64, 32);

    // Slurm.
    let err = make(
        &dir,
        "slurm",
        "slurm",
        &[
            "--cpus",
            "3",
            "--mem",
            "6G",
            "--time",
            "1-2:30",
            "--gpus",
            "1",
            "--partition",
            "gpu,cpu",
            "--account",
            "show_a",
            "--qos",
            "high",
            "--sbatch-arg=--constraint=avx2",
            "--sbatch-arg=--comment=two words",
        ],
    );
    assert!(
        err.contains("each task asks for 3 CPU(s), 6.0 GiB memory, 1 GPU(s), time limit 1-02:30:00, partition gpu,cpu, account show_a, qos high"),
        "{err}"
    );
    let array = std::fs::read_to_string(dir.join("slurm/array.sbatch")).unwrap();
    let d = sbatch_directives(&array);
    for want in [
        "--cpus-per-task=3",
        "--mem=6144M",
        "--time=1-02:30:00",
        "--gpus=1",
        "--partition=gpu,cpu",
        "--account=show_a",
        "--qos=high",
        "--constraint=avx2",
        "--comment=\"two words\"",
    ] {
        assert!(d.iter().any(|x| x == want), "{want}: {d:?}");
    }
    let verify = std::fs::read_to_string(dir.join("slurm/verify.sbatch")).unwrap();
    let v = sbatch_directives(&verify);
    assert!(v.contains(&"--cpus-per-task=1".to_string()), "{v:?}");
    assert!(!v.iter().any(|x| x.starts_with("--gpus")), "{v:?}");
    for f in ["array.sbatch", "verify.sbatch", "submit.sh"] {
        bash_parses(&dir.join("slurm").join(f));
    }
    // The task runs as many workers as its CPUs (no --jobs given).
    assert!(array.contains("--jobs=3"), "{array}");

    // Open Job Description.
    make(
        &dir,
        "openjd",
        "ojd",
        &[
            "--cpus",
            "2",
            "--mem",
            "1500M",
            "--time",
            "90",
            "--verify-time",
            "15",
            "--os-family",
            "linux",
            "--host-requirement",
            "attr.worker.cpu.arch=x86_64",
            "--host-requirement",
            "amount.worker.gpu.memory=8192",
        ],
    );
    let t: serde_json::Value =
        serde_norway::from_str(&std::fs::read_to_string(dir.join("ojd/template.yaml")).unwrap())
            .unwrap();
    let apply = &t["steps"][0];
    let amounts = &apply["hostRequirements"]["amounts"];
    let amount = |n: &str| {
        amounts
            .as_array()
            .unwrap()
            .iter()
            .find(|a| a["name"] == n)
            .map(|a| a["min"].clone())
    };
    assert_eq!(amount("amount.worker.vcpu"), Some(2.into()));
    assert_eq!(amount("amount.worker.memory"), Some(1500.into()));
    assert_eq!(amount("amount.worker.gpu.memory"), Some(8192.into()));
    assert_eq!(amount("amount.worker.gpu"), None);
    let attrs = apply["hostRequirements"]["attributes"].as_array().unwrap();
    assert!(attrs
        .iter()
        .any(|a| a["name"] == "attr.worker.os.family" && a["anyOf"][0] == "linux"));
    assert_eq!(apply["script"]["actions"]["onRun"]["timeout"], 5400);
    assert_eq!(t["steps"][1]["script"]["actions"]["onRun"]["timeout"], 900);
    assert_eq!(
        t["steps"][1]["hostRequirements"]["amounts"][0]["min"], 1,
        "the Verify step asks one vCPU"
    );
    if have("openjd") {
        assert_ok(
            &Command::new("openjd")
                .arg("check")
                .arg(dir.join("ojd/template.yaml"))
                .output()
                .unwrap(),
        );
    }

    // Kubernetes: resources, node selector, tolerations, a time limit per pod; the defaults
    // (no --cpus, --mem) from the batch, printed.
    let err = make(
        &dir,
        "k8s",
        "k8s",
        &[
            "--path-map",
            &format!("{}=/data/show", dir.display()),
            "--gpus",
            "1",
            "--time",
            "2:00:00",
            "--node-selector",
            "node.kubernetes.io/instance-type=g5.xlarge",
            "--node-selector",
            "pool=render",
            "--toleration",
            "nvidia.com/gpu:NoSchedule",
            "--toleration",
            "dedicated=render:NoExecute",
        ],
    );
    // 64×32 plates of R, G, B only: a decoded frame holds 12 bytes a pixel of camera RGB; 4
    // jobs + 2 frames at once, 256 MiB besides, a quarter more.
    let frame = 64 * 32 * 12;
    let mib = (256 + (6 * frame as u64).div_ceil(1 << 20)) * 5 / 4;
    assert!(
        err.contains(&format!("each task asks for 4 CPU(s), {mib} MiB memory, 1 GPU(s), time limit 0-02:00:00; memory from the batch: (4 jobs + 2) × 1 MiB frame of 64×32 (largest of 3 header(s) read) + 256 MiB, + 25%; apply runs --jobs 4")),
        "{err}"
    );
    assert!(!err.contains("warning"), "{err}");
    let docs = yaml_docs(&dir.join("k8s/job.yaml"));
    let pod = &docs[1]["spec"]["template"]["spec"];
    let c = &pod["containers"][0];
    assert_eq!(c["resources"]["requests"]["cpu"], "4");
    assert_eq!(c["resources"]["requests"]["memory"], format!("{mib}Mi"));
    assert_eq!(c["resources"]["limits"]["memory"], format!("{mib}Mi"));
    assert_eq!(c["resources"]["limits"]["nvidia.com/gpu"], "1");
    assert_eq!(pod["nodeSelector"]["pool"], "render");
    assert_eq!(pod["activeDeadlineSeconds"], 7200);
    assert_eq!(
        pod["tolerations"],
        serde_json::json!([
            {"key": "nvidia.com/gpu", "operator": "Exists", "effect": "NoSchedule"},
            {"key": "dedicated", "operator": "Equal", "value": "render", "effect": "NoExecute"}
        ])
    );
    let vpod = &yaml_docs(&dir.join("k8s/verify.yaml"))[0]["spec"]["template"]["spec"];
    assert!(vpod["containers"][0]["resources"]["limits"]["nvidia.com/gpu"].is_null());
    assert!(vpod["activeDeadlineSeconds"].is_null());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Hostile or malformed values are refused with the rule, and no job file is written.
#[test]
fn hostile_resource_values_are_refused_before_writing() {
    let dir = tempdir("farm-res-hostile");
    batch(&dir, 1, 8, 8);
    let cases: [(&str, &[&str], &str); 18] = [
        ("slurm", &["--mem", "8G\n#SBATCH --wrap=x"], "--mem"),
        ("slurm", &["--mem", "100T"], "--mem"),
        ("slurm", &["--time", "1:2:3:4"], "--time"),
        ("slurm", &["--time", "400-0"], "--time"),
        ("slurm", &["--cpus", "0"], "--cpus"),
        ("slurm", &["--cpus", "99999"], "--cpus"),
        ("slurm", &["--partition", "a b"], "--partition"),
        ("slurm", &["--sbatch-arg=--comment=a'b"], "--sbatch-arg"),
        ("slurm", &["--sbatch-arg=--mem=1G"], "set it with --mem"),
        (
            "k8s",
            &["--node-selector", "k=v\nhostNetwork: true"],
            "--node-selector",
        ),
        ("k8s", &["--toleration", "k=v:Always"], "--toleration"),
        ("k8s", &["--name", "Plates_1"], "RFC 1123 DNS label"),
        ("k8s", &["--pod-spec", "containers=[]"], "set it with"),
        ("k8s", &["--gpu-resource", "gpu"], "--gpu-resource"),
        ("slurm", &["--verify-time", "0"], "--verify-time"),
        (
            "slurm",
            &["--pod-spec", "priorityClassName=\"x\""],
            "--pod-spec is not for `nsrm farm slurm`",
        ),
        (
            "k8s",
            &["--partition", "gpu"],
            "--partition is not for `nsrm farm k8s`",
        ),
        (
            "openjd",
            &["--host-requirement", "attr.custom.x={{Param.Model}}"],
            "--host-requirement",
        ),
    ];
    for (engine, flags, says) in cases {
        let mut args = vec!["farm", engine, "--shards", "1", "--job-dir", "job"];
        if engine == "k8s" {
            args.extend(["--image", "i", "--claim", "c"]);
        }
        args.extend(flags);
        args.extend(["--model", "m.json", "-o", "out", "in"]);
        let o = nsrm_in(&dir, &args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{flags:?}: {err}");
        assert!(err.contains(says), "{flags:?}: {err}");
        assert!(!dir.join("job").exists(), "{flags:?} wrote files");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The generated Kubernetes manifests are valid against the Kubernetes API's schema (PyPI
/// `kubernetes-validate`, strict: no unknown field), for the oldest version with
/// `backoffLimitPerIndex` (1.29) and the newest the package knows; objects carry the batch's
/// label; two batches get different names and labels; paths off the claim are warned about.
#[test]
fn kubernetes_manifests_are_valid_named_and_labelled() {
    let dir = tempdir("farm-k8s-schema");
    batch(&dir, 2, 8, 8);
    let map = format!("{}=/data/show", dir.display());
    let flags = [
        "--path-map",
        &map,
        "--gpus",
        "1",
        "--time",
        "30",
        "--node-selector",
        "pool=render",
        "--toleration",
        "nvidia.com/gpu:NoSchedule",
        "--verify-time",
        "20",
        "--gpu-resource",
        "amd.com/gpu",
        "--pod-spec",
        "priorityClassName=\"render\"",
        "--pod-spec",
        r#"securityContext={"runAsNonRoot":true,"runAsUser":1000}"#,
    ];
    make(&dir, "k8s", "a", &flags);
    let job_a = yaml_docs(&dir.join("a/job.yaml"));
    let name_a = job_a[1]["metadata"]["name"].as_str().unwrap().to_string();
    // The pass-through fields, the GPU's resource name and the verification's time limit.
    let pod = &job_a[1]["spec"]["template"]["spec"];
    assert_eq!(pod["priorityClassName"], "render");
    assert_eq!(pod["securityContext"]["runAsUser"], 1000);
    assert_eq!(
        pod["containers"][0]["resources"]["limits"]["amd.com/gpu"],
        "1"
    );
    assert!(pod["containers"][0]["resources"]["limits"]["nvidia.com/gpu"].is_null());
    assert_eq!(pod["activeDeadlineSeconds"], 1800);
    let vpod = &yaml_docs(&dir.join("a/verify.yaml"))[0]["spec"]["template"]["spec"];
    assert_eq!(vpod["activeDeadlineSeconds"], 1200);
    assert_eq!(vpod["priorityClassName"], "render");
    assert!(
        name_a.starts_with("nsrm-") && name_a.len() == 17,
        "{name_a}"
    );
    for doc in job_a.iter().chain(&yaml_docs(&dir.join("a/verify.yaml"))) {
        assert_eq!(doc["metadata"]["labels"]["nsrm.batch"], name_a.as_str());
    }
    assert_eq!(
        job_a[1]["spec"]["template"]["metadata"]["labels"]["nsrm.batch"],
        name_a.as_str()
    );
    // Another batch (another output directory): another name and label; the same batch made
    // again: the same.
    let mut other = flags.to_vec();
    other.push("--overwrite");
    make(&dir, "k8s", "a", &other);
    assert_eq!(
        yaml_docs(&dir.join("a/job.yaml"))[1]["metadata"]["name"],
        name_a.as_str()
    );
    let o = nsrm_ok(
        &dir,
        &[
            "farm",
            "k8s",
            "--shards",
            "2",
            "--job-dir",
            "b",
            "--image",
            "nsrm:1",
            "--claim",
            "plates",
            "--path-map",
            &map,
            "--device",
            "cpu",
            "--model",
            "m.json",
            "-o",
            "out2",
            "in",
        ],
    );
    let job_b = yaml_docs(&dir.join("b/job.yaml"));
    assert_ne!(
        job_b[1]["metadata"]["name"],
        name_a.as_str(),
        "{}",
        stderr(&o)
    );
    assert_ne!(
        job_b[1]["metadata"]["labels"]["nsrm.batch"],
        name_a.as_str()
    );

    // Without --path-map the pods would not find the files: a warning with the fix.
    let err = make(&dir, "k8s", "c", &[]);
    assert!(
        err.contains("warning: 4 path(s) of the job are not under the claim's mount /data"),
        "{err}"
    );
    assert!(err.contains("--path-map"), "{err}");

    if !have("kubernetes-validate") {
        return;
    }
    for version in ["1.29.0", "1.37.0"] {
        let o = Command::new("kubernetes-validate")
            .args(["--strict", "-k", version])
            .arg(dir.join("a/job.yaml"))
            .arg(dir.join("a/verify.yaml"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
        assert!(o.status.success(), "{version}: {text}");
        assert!(!text.contains("ERROR"), "{version}: {text}");
    }
    // The validator is not a rubber stamp: a wrong type is refused.
    let bad = dir.join("bad.yaml");
    let text = std::fs::read_to_string(dir.join("a/verify.yaml"))
        .unwrap()
        .replace("backoffLimit: 0", "backoffLimit: none");
    std::fs::write(&bad, text).unwrap();
    let o = Command::new("kubernetes-validate")
        .arg("--strict")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A farm task whose stderr is not a terminal (a farm's log): the log starts with the task's
/// header (nsrm version, batch, shard, host, frames, device), says the device opened, shows a
/// line per frame with counts, rate and ETA, and ends with the shard's summary.
#[test]
fn a_farm_task_log_has_a_header_and_a_line_per_frame() {
    let dir = tempdir("farm-log");
    batch(&dir, 3, 16, 16);
    let o = nsrm_in(
        &dir,
        &[
            "farm",
            "run",
            "--shard",
            "1/1",
            "--batch",
            "plates-0042",
            "--",
            "--device",
            "cpu",
            "--jobs",
            "1",
            "--model",
            "m.json",
            "-o",
            "out",
            "in",
        ],
    );
    let err = stderr(&o);
    assert_ok(&o);
    let lines: Vec<&str> = err.lines().collect();
    assert!(
        lines[0].starts_with(&format!(
            "nsrm farm run: nsrm {}, batch plates-0042, shard 1/1, host ",
            env!("CARGO_PKG_VERSION")
        )),
        "{err}"
    );
    assert!(
        lines[1].starts_with("nsrm farm run: 3 frame(s) in this shard, of 3 in the batch; device asked: --device cpu, --jobs 1"),
        "{err}"
    );
    assert!(
        lines[2].starts_with("nsrm farm run: 0 finished already (kept or adopted), 3 to convert"),
        "{err}"
    );
    assert!(
        lines[3].starts_with("nsrm apply: correcting 3 frame(s) on the CPU"),
        "{err}"
    );
    let progress: Vec<&&str> = lines
        .iter()
        .filter(|l| l.contains(" frames (") && l.contains("frames/s"))
        .collect();
    // One a second at most, and always the last.
    assert!(!progress.is_empty(), "{err}");
    assert!(
        progress
            .last()
            .unwrap()
            .contains("3/3 frames (100%), 0 failed;"),
        "{err}"
    );
    assert!(
        progress.last().unwrap().contains("done; wrote shot_"),
        "{err}"
    );
    assert!(
        lines
            .last()
            .unwrap()
            .starts_with("nsrm farm run: shard 1/1: 3 converted"),
        "{err}"
    );
    // A re-run converts nothing, and its header still says so.
    let o = nsrm_in(
        &dir,
        &[
            "farm", "run", "--shard", "1/1", "--", "--device", "cpu", "--jobs", "1", "--model",
            "m.json", "-o", "out", "in",
        ],
    );
    let err = stderr(&o);
    assert_ok(&o);
    assert!(err.contains("batch (not named)"), "{err}");
    assert!(
        err.contains("3 finished already (kept or adopted), 0 to convert"),
        "{err}"
    );
    assert!(!err.contains("frames/s"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The generated jobs pass the batch's name to each task, for its log's header.
#[test]
fn the_jobs_name_the_batch_to_their_tasks() {
    let dir = tempdir("farm-batch-arg");
    batch(&dir, 1, 8, 8);
    make(&dir, "slurm", "s", &["--name", "plates"]);
    let array = std::fs::read_to_string(dir.join("s/array.sbatch")).unwrap();
    assert!(
        array.contains(" farm run --batch plates --shard "),
        "{array}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
