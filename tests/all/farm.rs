//! `nsrm farm`: byte-reproducible outputs, retry-safe shards with manifests, and the generated
//! jobs run on real engines: `openjd check` / `openjd run` (Open Job Description, the job format
//! of AWS Deadline Cloud) and a single-node Slurm started here; the Kubernetes manifest is
//! parsed and checked for shape. The engines are installed by `.ci/install.d/50-farm.sh`.

use crate::common::{assert_ok, model, nsrm_in, nsrm_ok, stderr, tempdir};
use ::exr::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Prints SKIP and returns false when a tool is absent; under CI=true that is a failure.
pub(crate) fn have(tool: &str) -> bool {
    let found = Command::new("sh")
        .arg("-c")
        .arg(format!("command -v {tool}"))
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "{tool} is missing under CI=true (.ci/install.d/50-farm.sh installs it)"
        );
        eprintln!("SKIP: {tool} is not installed (.ci/install.d/50-farm.sh installs it)");
    }
    found
}

/// A linear camera-RGB EXR with many custom header attributes (the ones the `exr` crate kept
/// in a hash map and wrote in a random order), scanline or tiled.
fn plate(path: &Path, w: usize, h: usize, seed: usize, tiled: bool) {
    let n = w * h;
    let ch = |c: usize| {
        FlatSamples::F32(
            (0..n)
                .map(|i| ((i * (c + 3) + seed * 7919) % 1009) as f32 / 1009.0)
                .collect(),
        )
    };
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![
        AnyChannel::new("R", ch(0)),
        AnyChannel::new("G", ch(1)),
        AnyChannel::new("B", ch(2)),
    ]));
    let mut attrs = LayerAttributes::default();
    for k in 0..12 {
        attrs.other.insert(
            Text::from(format!("studio{k}").as_str()),
            AttributeValue::Text(Text::from(format!("value {k} of {seed}").as_str())),
        );
    }
    attrs
        .other
        .insert(Text::from("frameIndex"), AttributeValue::I32(seed as i32));
    let blocks = if tiled {
        Blocks::Tiles(Vec2(16, 16))
    } else {
        Blocks::ScanLines
    };
    let layer = Layer::new(
        Vec2(w, h),
        attrs,
        Encoding {
            compression: Compression::ZIP16,
            blocks,
            line_order: LineOrder::Increasing,
        },
        channels,
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

/// The attribute names of an EXR's (single) header, in file order.
fn header_names(bytes: &[u8]) -> Vec<String> {
    let mut at = 8;
    let mut names = Vec::new();
    while bytes[at] != 0 {
        let end = at + bytes[at..].iter().position(|&b| b == 0).unwrap();
        names.push(String::from_utf8_lossy(&bytes[at..end]).into_owned());
        let ty_end = end + 1 + bytes[end + 1..].iter().position(|&b| b == 0).unwrap();
        let size = i32::from_le_bytes(bytes[ty_end + 1..ty_end + 5].try_into().unwrap()) as usize;
        at = ty_end + 5 + size;
    }
    names
}

/// Every file of `dir` (name → bytes), manifests left out.
fn outputs(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| !e.file_name().to_string_lossy().starts_with("nsrm-farm."))
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

fn manifest(dir: &Path, k: usize, n: usize) -> serde_json::Value {
    let p = dir.join(format!("nsrm-farm.shard-{k:04}-of-{n:04}.json"));
    serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap()
}

/// `how` of each output a manifest records.
fn hows(m: &serde_json::Value) -> Vec<(String, String)> {
    m["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["output"].as_str().unwrap().to_string(),
                e["how"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

#[cfg(unix)]
fn identity(p: &Path) -> (u64, i64, i64) {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(p).unwrap();
    (m.ino(), m.mtime(), m.mtime_nsec())
}

/// Two `nsrm apply` runs (two processes, two hash seeds) write the same bytes: EXR through the
/// chunk path (scanline) and the `exr` crate's (tiled input), with previews, and TIFF.
#[test]
fn apply_writes_the_same_bytes_every_run() {
    let dir = tempdir("farm-repro");
    model(&dir);
    std::fs::create_dir(dir.join("in")).unwrap();
    plate(&dir.join("in/scan.0001.exr"), 40, 24, 1, false);
    plate(&dir.join("in/tiled.0001.exr"), 40, 24, 2, true);
    for (run, extra) in [("a", "exr"), ("b", "exr"), ("c", "tiff"), ("d", "tiff")] {
        let out = format!("{run}-out");
        let prev = format!("{run}-prev");
        let mut args = vec![
            "apply",
            "--device",
            "cpu",
            "--model",
            "m.json",
            "-o",
            &out,
            "--preview",
            &prev,
            "--format",
            extra,
        ];
        if extra == "tiff" {
            args.push("in/scan.0001.exr");
        } else {
            args.push("in");
        }
        nsrm_ok(&dir, &args);
    }
    let a = outputs(&dir.join("a-out"));
    assert_eq!(a.len(), 2);
    assert_eq!(a, outputs(&dir.join("b-out")));
    assert_eq!(outputs(&dir.join("a-prev")), outputs(&dir.join("b-prev")));
    assert_eq!(outputs(&dir.join("c-out")), outputs(&dir.join("d-out")));
    // The custom attributes are there, in name order (as are the standard ones).
    for (name, bytes) in &a {
        let names = header_names(bytes);
        assert!(
            names.iter().filter(|n| n.starts_with("studio")).count() == 12,
            "{name}: {names:?}"
        );
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(names, sorted, "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A batch of plates for the farm tests: `n` scanline EXRs of `w`×`h` in `dir/in`.
pub(crate) fn batch(dir: &Path, n: usize, w: usize, h: usize) {
    std::fs::create_dir_all(dir.join("in")).unwrap();
    model(dir);
    for i in 0..n {
        plate(
            &dir.join(format!("in/shot.{:04}.exr", i + 1)),
            w,
            h,
            i,
            false,
        );
    }
}

/// `nsrm farm run` (no engine): the shards' union equals one `nsrm apply`; a re-run keeps
/// every finished output (same inode and mtime); a stale temporary of its own outputs is
/// removed, another shard's is left; a broken output is replaced; verify finds each fault.
#[test]
fn shards_retry_safely_and_verify_names_what_is_wrong() {
    let dir = tempdir("farm-run");
    batch(&dir, 5, 32, 16);
    let run = |k: usize, extra: &[&str]| {
        let shard = format!("{k}/2");
        let mut args = vec!["farm", "run", "--shard", &shard, "--"];
        args.extend(["--device", "cpu", "--model", "m.json", "-o", "out"]);
        args.extend(extra);
        args.push("in");
        nsrm_in(&dir, &args)
    };
    let verify = || nsrm_in(&dir, &["farm", "verify", "out", "--model", "m.json"]);
    assert_ok(&run(1, &[]));
    let v = verify();
    assert_eq!(v.status.code(), Some(1));
    assert!(
        stderr(&v).contains("shard 2/2: no manifest"),
        "{}",
        stderr(&v)
    );
    assert_ok(&run(2, &[]));
    let v = verify();
    assert_ok(&v);
    nsrm_ok(
        &dir,
        &[
            "apply", "--device", "cpu", "--model", "m.json", "-o", "single", "in",
        ],
    );
    assert_eq!(outputs(&dir.join("out")), outputs(&dir.join("single")));
    let m1 = manifest(&dir.join("out"), 1, 2);
    assert!(hows(&m1).iter().all(|(_, h)| h == "converted"), "{m1}");
    assert_eq!(m1["outputs"].as_array().unwrap().len(), 3);

    // A re-run keeps everything: same files, not rewritten.
    let first = dir.join("out/shot_xyz.0001.exr");
    let before = identity(&first);
    // A killed run's temporaries: one of shard 1's outputs, one of shard 2's.
    let own = dir.join("out/.shot_xyz.0003.exr.nsrm-4242-0123456789abcdef.tmp");
    let other = dir.join("out/.shot_xyz.0002.exr.nsrm-4242-0123456789abcdef.tmp");
    std::fs::write(&own, b"half a frame").unwrap();
    std::fs::write(&other, b"half a frame").unwrap();
    let again = run(1, &[]);
    assert_ok(&again);
    assert_eq!(identity(&first), before);
    assert!(!own.exists() && other.exists(), "{}", stderr(&again));
    let m1 = manifest(&dir.join("out"), 1, 2);
    assert!(hows(&m1).iter().all(|(_, h)| h == "kept"), "{m1}");
    assert_eq!(
        m1["stale_temporaries_removed"],
        serde_json::json!([".shot_xyz.0003.exr.nsrm-4242-0123456789abcdef.tmp"])
    );
    let v = verify();
    assert_eq!(v.status.code(), Some(1));
    assert!(
        stderr(&v).contains("an nsrm temporary is left"),
        "{}",
        stderr(&v)
    );
    std::fs::remove_file(&other).unwrap();
    assert_ok(&verify());

    // A truncated output: verify names it; the shard's re-run replaces it.
    let third = dir.join("out/shot_xyz.0003.exr");
    let full = std::fs::read(&third).unwrap();
    std::fs::write(&third, &full[..full.len() / 2]).unwrap();
    let v = verify();
    assert_eq!(v.status.code(), Some(1));
    assert!(
        stderr(&v).contains("shot_xyz.0003.exr") && stderr(&v).contains("bytes"),
        "{}",
        stderr(&v)
    );
    assert_ok(&run(1, &[]));
    assert_eq!(std::fs::read(&third).unwrap(), full);
    let m1 = manifest(&dir.join("out"), 1, 2);
    assert!(
        hows(&m1).contains(&("shot_xyz.0003.exr".into(), "replaced".into())),
        "{m1}"
    );
    assert_eq!(identity(&first), before);
    assert_ok(&verify());

    // Without a manifest (a run killed before writing it), complete outputs are adopted.
    std::fs::remove_file(dir.join("out/nsrm-farm.shard-0001-of-0002.json")).unwrap();
    assert_ok(&run(1, &[]));
    let m1 = manifest(&dir.join("out"), 1, 2);
    assert!(hows(&m1).iter().all(|(_, h)| h == "adopted"), "{m1}");
    assert_eq!(identity(&first), before);

    // Another model: the shard's outputs are redone, and verify tells the models apart.
    let m = std::fs::read_to_string(dir.join("m.json")).unwrap();
    std::fs::write(dir.join("m2.json"), m.replace("50.0", "51.0")).unwrap();
    let out = nsrm_in(
        &dir,
        &[
            "farm", "run", "--shard", "2/2", "--", "--device", "cpu", "--model", "m2.json", "-o",
            "out", "in",
        ],
    );
    assert_ok(&out);
    let m2 = manifest(&dir.join("out"), 2, 2);
    assert!(hows(&m2).iter().all(|(_, h)| h == "replaced"), "{m2}");
    let v = verify();
    assert_eq!(v.status.code(), Some(1));
    assert!(
        stderr(&v).contains("applied another model"),
        "{}",
        stderr(&v)
    );

    // The task decides the per-run policies itself.
    for flag in ["--overwrite", "--skip-existing", "--dry-run"] {
        let o = nsrm_in(
            &dir,
            &[
                "farm", "run", "--shard", "1/2", "--", "--model", "m.json", "-o", "out", flag, "in",
            ],
        );
        assert_eq!(o.status.code(), Some(2), "{flag}: {}", stderr(&o));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The Open Job Description bundle passes `openjd check`; `openjd run` runs every task of the
/// Apply step and then Verify, on paths made on a "submitter" and mapped to where the "worker"
/// finds them (Model and OutputDir by openjd, the listed inputs by nsrm from the session's
/// rules file). The union of the shards equals one `nsrm apply`; a second run keeps everything.
#[test]
fn openjd_runs_every_task_and_the_union_equals_one_apply() {
    if !have("openjd") {
        return;
    }
    let root = tempdir("farm-openjd");
    let submit = root.join("submitter");
    batch(&submit, 7, 48, 20);
    let program = env!("CARGO_BIN_EXE_nsrm");
    let made = nsrm_in(
        &submit,
        &[
            "farm",
            "openjd",
            "--shards",
            "3",
            "--job-dir",
            "job",
            "--program",
            program,
            "--name",
            "plates",
            "--device",
            "cpu",
            "--model",
            "m.json",
            "-o",
            "out",
            "in",
        ],
    );
    assert_ok(&made);
    for f in [
        "template.yaml",
        "parameter_values.yaml",
        "job_parameters.json",
    ] {
        assert!(submit.join("job").join(f).is_file(), "{f}");
    }
    // Deadline Cloud's own bundle reader: job attachments would upload every input, the input
    // list and the model, and download the output directory.
    if let Some(refs) = deadline_asset_references(&submit.join("job")) {
        let sorted = |v: &serde_json::Value| {
            let mut v: Vec<String> = v
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_str().unwrap().to_string())
                .collect();
            v.sort();
            v
        };
        let mut want: Vec<String> = std::fs::read_dir(submit.join("in"))
            .unwrap()
            .map(|e| e.unwrap().path().to_str().unwrap().to_string())
            .collect();
        want.push(submit.join("job/inputs.txt").to_str().unwrap().into());
        want.push(submit.join("m.json").to_str().unwrap().into());
        want.sort();
        let refs = &refs["assetReferences"];
        assert_eq!(sorted(&refs["inputs"]["filenames"]), want, "{refs}");
        assert_eq!(
            sorted(&refs["outputs"]["directories"]),
            [submit.join("out").to_str().unwrap()],
            "{refs}"
        );
    }
    // Refused without --overwrite the second time.
    let again = nsrm_in(
        &submit,
        &[
            "farm",
            "openjd",
            "--shards",
            "3",
            "--job-dir",
            "job",
            "--model",
            "m.json",
            "-o",
            "out",
            "in",
        ],
    );
    assert!(!again.status.success());
    // The whole tree moves: the worker finds it elsewhere.
    let worker = root.join("worker");
    let rules = worker.join("rules.json");
    let template = moved_to_worker(&submit, &worker, &rules);
    let openjd = |step: &str| {
        let t = Instant::now();
        let o = Command::new("openjd")
            .arg("run")
            .arg(&template)
            .args(["--step", step, "-p"])
            .arg(format!(
                "file://{}",
                worker.join("job/job_parameters.json").display()
            ))
            .arg("--path-mapping-rules")
            .arg(format!("file://{}", rules.display()))
            .env("NO_COLOR", "1")
            .output()
            .unwrap();
        let log = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
        assert!(o.status.success(), "openjd run --step {step}:\n{log}");
        eprintln!(
            "openjd run --step {step}: {:.2} s",
            t.elapsed().as_secs_f64()
        );
        log
    };
    let log = openjd("Apply");
    assert_eq!(log.matches("nsrm farm run: shard").count(), 3, "{log}");
    let log = openjd("Verify");
    assert!(log.contains("nsrm farm verify: OK"), "{log}");
    nsrm_ok(
        &worker,
        &[
            "apply", "--device", "cpu", "--model", "m.json", "-o", "single", "in",
        ],
    );
    let out = outputs(&worker.join("out"));
    assert_eq!(out.len(), 7);
    assert_eq!(out, outputs(&worker.join("single")));
    for k in 1..=3 {
        let m = manifest(&worker.join("out"), k, 3);
        assert!(hows(&m).iter().all(|(_, h)| h == "converted"), "{m}");
        // The worker's paths, not the submitter's.
        assert!(
            m["model"]["path"]
                .as_str()
                .unwrap()
                .starts_with(worker.to_str().unwrap()),
            "{m}"
        );
    }
    // A retry of the whole step redoes nothing.
    let first = worker.join("out/shot_xyz.0001.exr");
    let before = identity(&first);
    let log = openjd("Apply");
    assert_eq!(log.matches("0 converted, 0 replaced").count(), 3, "{log}");
    assert_eq!(identity(&first), before);
    let _ = std::fs::remove_dir_all(&root);
}

/// The Kubernetes manifest parses as YAML and has the Indexed Job's shape: completions and
/// the index mapping, the image and claim given, the input list in a ConfigMap, mapped paths.
#[test]
fn kubernetes_manifest_has_the_indexed_job_shape() {
    let dir = tempdir("farm-k8s");
    batch(&dir, 3, 8, 8);
    let root = dir.to_str().unwrap();
    let map = format!("{root}=/data/show");
    nsrm_ok(
        &dir,
        &[
            "farm",
            "k8s",
            "--shards",
            "2",
            "--job-dir",
            "job",
            "--image",
            "registry.example/nsrm:1",
            "--claim",
            "show-pvc",
            "--mount",
            "/data",
            "--parallelism",
            "5",
            "--path-map",
            &map,
            "--model",
            "m.json",
            "-o",
            "out",
            "--output-space",
            "acescg",
            "in",
        ],
    );
    let text = std::fs::read_to_string(dir.join("job/job.yaml")).unwrap();
    let docs: Vec<serde_json::Value> = serde_norway::Deserializer::from_str(&text)
        .map(|d| serde::Deserialize::deserialize(d).unwrap())
        .collect();
    assert_eq!(docs.len(), 2, "{text}");
    let (cm, job) = (&docs[0], &docs[1]);
    assert_eq!(cm["kind"], "ConfigMap");
    let list = cm["data"]["inputs.txt"].as_str().unwrap();
    assert_eq!(
        list,
        "/data/show/in/shot.0001.exr\n/data/show/in/shot.0002.exr\n/data/show/in/shot.0003.exr\n"
    );
    assert_eq!(job["apiVersion"], "batch/v1");
    assert_eq!(job["kind"], "Job");
    let spec = &job["spec"];
    assert_eq!(spec["completionMode"], "Indexed");
    assert_eq!(spec["completions"], 2);
    assert_eq!(spec["parallelism"], 2);
    let pod = &spec["template"]["spec"];
    assert_eq!(pod["restartPolicy"], "Never");
    let c = &pod["containers"][0];
    assert_eq!(c["image"], "registry.example/nsrm:1");
    let script = c["command"][2].as_str().unwrap();
    assert!(
        script.contains("$((JOB_COMPLETION_INDEX + 1))/2"),
        "{script}"
    );
    assert!(
        script.contains("--inputs-from /etc/nsrm-batch/inputs.txt"),
        "{script}"
    );
    assert!(
        script.contains("--model /data/show/m.json -o /data/show/out"),
        "{script}"
    );
    assert!(script.contains("--output-space acescg"), "{script}");
    let mounts = c["volumeMounts"].as_array().unwrap();
    assert!(mounts
        .iter()
        .any(|m| m["mountPath"] == "/data" && m["name"] == "data"));
    let vols = pod["volumes"].as_array().unwrap();
    assert!(vols
        .iter()
        .any(|v| v["persistentVolumeClaim"]["claimName"] == "show-pvc"));
    assert!(vols
        .iter()
        .any(|v| v["configMap"]["name"] == cm["metadata"]["name"]));
    let verify: serde_json::Value =
        serde_norway::from_str(&std::fs::read_to_string(dir.join("job/verify.yaml")).unwrap())
            .unwrap();
    let cmd = verify["spec"]["template"]["spec"]["containers"][0]["command"][2]
        .as_str()
        .unwrap();
    assert!(
        cmd.contains("farm verify /data/show/out --shards 2 --model /data/show/m.json"),
        "{cmd}"
    );
    // The script runs in a shell as it stands: index 1 is shard 2/2.
    let o = Command::new("sh")
        .arg("-c")
        .arg(script.replace("exec ", "echo "))
        .env("JOB_COMPLETION_INDEX", "1")
        .output()
        .unwrap();
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("--shard 2/2 "),
        "{o:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Daemons this test started, stopped by their PIDs when it ends (also on a panic).
struct Daemons {
    children: Vec<(String, Child)>,
    dir: PathBuf,
}

impl Daemons {
    fn start(&mut self, name: &str, cmd: &mut Command) {
        let log = std::fs::File::create(self.dir.join(format!("{name}.out"))).unwrap();
        let child = cmd
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .stdin(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        self.children.push((name.to_string(), child));
    }

    fn logs(&self) -> String {
        let mut s = String::new();
        for f in [
            "munged.out",
            "slurmctld.out",
            "slurmd.out",
            "slurmctld.log",
            "slurmd.log",
        ] {
            if let Ok(t) = std::fs::read_to_string(self.dir.join(f)) {
                let tail: Vec<&str> = t.lines().rev().take(15).collect();
                s += &format!(
                    "--- {f}\n{}\n",
                    tail.into_iter().rev().collect::<Vec<_>>().join("\n")
                );
            }
        }
        s
    }
}

impl Drop for Daemons {
    fn drop(&mut self) {
        // Newest first: slurmd, slurmctld, munged. SIGTERM, then SIGKILL after 10 s.
        for (name, child) in self.children.iter_mut().rev() {
            let pid = child.id().to_string();
            let _ = Command::new("kill").args(["-TERM", &pid]).status();
            let t = Instant::now();
            while t.elapsed() < Duration::from_secs(10) {
                if let Ok(Some(_)) = child.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            if let Ok(None) = child.try_wait() {
                eprintln!("{name} (pid {pid}) ignored SIGTERM; killing it");
                let _ = child.kill();
                let _ = child.wait();
            }
        }
    }
}

/// Polls `f` every `every` until it gives `Some`, for at most `limit`.
fn poll<T>(limit: Duration, every: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let t = Instant::now();
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if t.elapsed() > limit {
            return None;
        }
        std::thread::sleep(every);
    }
}

/// A single-node Slurm started here runs the generated array job. Shard 1 is first run alone
/// and killed (SIGKILL) part-way; the whole job (array + dependent verification) then completes
/// without redoing the frames the killed task finished, and equals one `nsrm apply`.
#[test]
fn slurm_runs_the_array_and_a_killed_task_resumes() {
    if !(have("slurmctld") && have("slurmd") && have("sbatch") && have("munged")) {
        return;
    }
    let uid = Command::new("id").arg("-u").output().unwrap();
    if String::from_utf8_lossy(&uid.stdout).trim() != "0" {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "the Slurm test needs root under CI"
        );
        eprintln!("SKIP: a single-node Slurm needs root here");
        return;
    }
    let dir = tempdir("farm-slurm");
    let sd = dir.join("slurm");
    std::fs::create_dir_all(sd.join("state")).unwrap();
    std::fs::create_dir_all(sd.join("spool")).unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&sd, std::fs::Permissions::from_mode(0o755)).unwrap();
        let key: Vec<u8> = (0..1024u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
            .collect();
        std::fs::write(sd.join("munge.key"), key).unwrap();
        std::fs::set_permissions(sd.join("munge.key"), std::fs::Permissions::from_mode(0o400))
            .unwrap();
    }
    let host = String::from_utf8(Command::new("hostname").arg("-s").output().unwrap().stdout)
        .unwrap()
        .trim()
        .to_string();
    let cpus = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let s = sd.display();
    let conf = sd.join("slurm.conf");
    std::fs::write(
        &conf,
        format!(
            "ClusterName=nsrmtest\nSlurmctldHost={host}(127.0.0.1)\nSlurmctldPort=16817\nSlurmdPort=16818\n\
             AuthType=auth/munge\nAuthInfo=socket={s}/munge.sock\nCredType=cred/munge\n\
             SlurmUser=root\nSlurmdUser=root\nStateSaveLocation={s}/state\nSlurmdSpoolDir={s}/spool\n\
             SlurmctldPidFile={s}/slurmctld.pid\nSlurmdPidFile={s}/slurmd.pid\n\
             SlurmctldLogFile={s}/slurmctld.log\nSlurmdLogFile={s}/slurmd.log\n\
             ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nJobAcctGatherType=jobacct_gather/none\n\
             AccountingStorageType=accounting_storage/none\nSelectType=select/cons_tres\n\
             SelectTypeParameters=CR_CPU_Memory\nReturnToService=2\nMpiDefault=none\nMailProg=/bin/true\n\
             MinJobAge=600\n\
             NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory=1000 State=UNKNOWN\n\
             PartitionName=main Nodes={host} Default=YES MaxTime=INFINITE State=UP\n"
        ),
    )
    .unwrap();
    let mut d = Daemons {
        children: Vec::new(),
        dir: sd.clone(),
    };
    d.start(
        "munged",
        Command::new("munged")
            .args(["-F", "-f"])
            .arg(format!("--socket={s}/munge.sock"))
            .arg(format!("--key-file={s}/munge.key"))
            .arg(format!("--pid-file={s}/munged.pid"))
            .arg(format!("--log-file={s}/munged.log"))
            .arg(format!("--seed-file={s}/munged.seed")),
    );
    assert!(
        poll(Duration::from_secs(10), Duration::from_millis(50), || sd
            .join("munge.sock")
            .exists()
            .then_some(()))
        .is_some(),
        "munged did not start:\n{}",
        d.logs()
    );
    d.start(
        "slurmctld",
        Command::new("slurmctld").arg("-D").arg("-f").arg(&conf),
    );
    d.start(
        "slurmd",
        Command::new("slurmd").arg("-D").arg("-f").arg(&conf),
    );
    let slurm = |prog: &str| {
        let mut c = Command::new(prog);
        c.env("SLURM_CONF", &conf);
        c
    };
    let t = Instant::now();
    let idle = poll(Duration::from_secs(60), Duration::from_millis(250), || {
        let o = slurm("sinfo").args(["-h", "-o", "%T"]).output().ok()?;
        (String::from_utf8_lossy(&o.stdout).trim() == "idle").then_some(())
    });
    assert!(idle.is_some(), "the node never became idle:\n{}", d.logs());
    eprintln!("slurm: node idle after {:.1} s", t.elapsed().as_secs_f64());

    // 10 plates in 2 shards; big enough, compressed hard enough and one worker each, so the
    // task is still running when it is killed.
    batch(&dir, 10, 512, 512);
    let program = env!("CARGO_BIN_EXE_nsrm");
    let apply_opts = [
        "--device",
        "cpu",
        "--jobs",
        "1",
        "--compression",
        "zip",
        "--zip-level",
        "12",
    ];
    let mut args = vec![
        "farm",
        "slurm",
        "--shards",
        "2",
        "--job-dir",
        "job",
        "--program",
        program,
        "--name",
        "plates",
        "--time",
        "10",
    ];
    args.extend(apply_opts);
    args.extend(["--model", "m.json", "-o", "out", "in"]);
    nsrm_ok(&dir, &args);
    let job = dir.join("job");

    let squeue_empty = || {
        let o = slurm("squeue").args(["-h"]).output().ok()?;
        (o.status.success() && o.stdout.is_empty()).then_some(())
    };
    // Shard 1 alone, killed once its first output is committed.
    let t = Instant::now();
    let o = slurm("sbatch")
        .args(["--parsable", "--array=1"])
        .arg("array.sbatch")
        .current_dir(&job)
        .output()
        .unwrap();
    assert_ok(&o);
    let first_job = String::from_utf8_lossy(&o.stdout).trim().to_string();
    // Slurm took the task's resources (memory is a consumable resource here: CR_CPU_Memory):
    // one CPU (--jobs 1), the memory nsrm derived from the batch, the time limit given.
    let array = std::fs::read_to_string(job.join("array.sbatch")).unwrap();
    let mem = array
        .lines()
        .find_map(|l| l.strip_prefix("#SBATCH --mem="))
        .expect("a --mem directive")
        .to_string();
    let shown = slurm("scontrol")
        .args(["show", "job", "-o", &first_job])
        .output()
        .unwrap();
    let shown = String::from_utf8_lossy(&shown.stdout).into_owned();
    assert!(shown.contains("TimeLimit=00:10:00"), "{shown}");
    assert!(shown.contains(&format!("mem={mem}")), "{mem}: {shown}");
    assert!(shown.contains("cpu=1,"), "{shown}");
    let shard1: Vec<PathBuf> = (0..10)
        .step_by(2)
        .map(|i| dir.join(format!("out/shot_xyz.{:04}.exr", i + 1)))
        .collect();
    let some = poll(Duration::from_secs(60), Duration::from_millis(5), || {
        shard1.iter().any(|p| p.exists()).then_some(())
    });
    assert!(some.is_some(), "shard 1 wrote nothing:\n{}", d.logs());
    let task = format!("{first_job}_1");
    assert_ok(
        // `--batch`: the signal itself, to the batch step (nsrm, exec'd by the script); a
        // plain `scancel --signal=KILL` cancels the job, which starts with SIGTERM.
        &slurm("scancel")
            .args(["--batch", "--signal=KILL", &task])
            .output()
            .unwrap(),
    );
    assert!(
        poll(
            Duration::from_secs(60),
            Duration::from_millis(100),
            squeue_empty
        )
        .is_some(),
        "the killed task did not end"
    );
    let finished: Vec<&PathBuf> = shard1.iter().filter(|p| p.exists()).collect();
    eprintln!(
        "slurm: shard 1 killed after {:.2} s with {} of {} outputs committed",
        t.elapsed().as_secs_f64(),
        finished.len(),
        shard1.len()
    );
    assert!(
        !finished.is_empty() && finished.len() < shard1.len(),
        "the kill was not part-way: {} of {}",
        finished.len(),
        shard1.len()
    );
    let task_log =
        std::fs::read_to_string(job.join(format!("plates-{first_job}_1.out"))).unwrap_or_default();
    assert!(
        !task_log.contains("interrupted by"),
        "not a SIGKILL: {task_log}"
    );
    assert!(
        !dir.join("out/nsrm-farm.shard-0001-of-0002.json").exists(),
        "{task_log}"
    );
    let before: Vec<_> = finished.iter().map(|p| identity(p)).collect();
    let stale = temporaries(&dir.join("out"));

    // The whole job: the array (both shards) and the verification after it.
    let t = Instant::now();
    let o = Command::new("sh")
        .arg(job.join("submit.sh"))
        .env("SLURM_CONF", &conf)
        .output()
        .unwrap();
    assert_ok(&o);
    assert!(
        poll(
            Duration::from_secs(180),
            Duration::from_millis(250),
            squeue_empty
        )
        .is_some(),
        "the job did not finish in 180 s:\n{}",
        d.logs()
    );
    eprintln!(
        "slurm: array of 2 tasks and the verification done in {:.1} s ({})",
        t.elapsed().as_secs_f64(),
        String::from_utf8_lossy(&o.stdout).trim()
    );
    let logs: Vec<(String, String)> = std::fs::read_dir(&job)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".out"))
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read_to_string(e.path()).unwrap_or_default(),
            )
        })
        .collect();
    let verify_log = logs
        .iter()
        .find(|(n, _)| n.starts_with("plates-verify-"))
        .map(|(_, t)| t.clone())
        .unwrap_or_default();
    assert!(verify_log.contains("nsrm farm verify: OK"), "{logs:?}");
    let m1 = manifest(&dir.join("out"), 1, 2);
    let h1 = hows(&m1);
    eprintln!(
        "slurm: shard 1 on re-run: {h1:?}; stale temporaries removed: {}",
        m1["stale_temporaries_removed"]
    );
    for (p, id) in finished.iter().zip(&before) {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        assert!(h1.contains(&(name, "adopted".to_string())), "{m1}");
        assert_eq!(identity(p), *id, "{} was rewritten", p.display());
    }
    assert_eq!(
        h1.iter().filter(|(_, h)| h == "converted").count(),
        shard1.len() - finished.len(),
        "{m1}"
    );
    assert_eq!(
        m1["stale_temporaries_removed"].as_array().unwrap().len(),
        stale.len(),
        "{m1} {stale:?}"
    );
    assert!(hows(&manifest(&dir.join("out"), 2, 2))
        .iter()
        .all(|(_, h)| h == "converted"));
    let mut single = vec!["apply"];
    single.extend(apply_opts);
    single.extend(["--model", "m.json", "-o", "single", "in"]);
    nsrm_ok(&dir, &single);
    assert_eq!(outputs(&dir.join("out")), outputs(&dir.join("single")));
    assert_ok(&nsrm_in(
        &dir,
        &[
            "farm", "verify", "out", "--shards", "2", "--model", "m.json",
        ],
    ));
    drop(d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The output temporaries in `dir` (`.NAME.nsrm-PID-RANDOM.tmp`, the form the output session
/// creates), sorted.
fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p.file_name().unwrap_or_default().to_string_lossy();
            name.starts_with('.') && name.contains(".nsrm-") && name.ends_with(".tmp")
        })
        .collect();
    found.sort();
    found
}

/// A shard manifest of one output, `name`, whose content is `bytes` (its true size and hash).
fn hostile_manifest(name: &str, bytes: &[u8], inputs: serde_json::Value) -> serde_json::Value {
    use sha2::{Digest, Sha256};
    let hex = |b: &[u8]| -> String { b.iter().map(|x| format!("{x:02x}")).collect() };
    serde_json::json!({
        "format": "nsrm-farm-shard/1", "nsrm_version": "0", "shard": 1, "shards": 1,
        "batch": {"inputs": inputs, "outputs_sha256": hex(&Sha256::digest(format!("{name}\n")))},
        "model": {"path": "m.json", "sha256": "00".repeat(32)},
        "settings": [], "failures": [], "stale_temporaries_removed": [],
        "outputs": [{"input": "in.exr", "output": name, "bytes": bytes.len(),
                     "sha256": hex(&Sha256::digest(bytes)), "how": "converted"}],
        "timings": {"started_unix": 0.0, "check_s": 0.0, "convert_s": 0.0, "hash_s": 0.0, "total_s": 0.0}
    })
}

/// `nsrm farm verify` under a 2 GB address-space limit (a count sized into an allocation
/// aborts there instead of swapping), in `dir`.
fn verify_bounded(dir: &Path, args: &[&str]) -> (std::process::Output, String) {
    let t = Instant::now();
    let o = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 2000000; exec \"$0\" farm verify \"$@\"")
        .arg(env!("CARGO_BIN_EXE_nsrm"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    let err = stderr(&o);
    crate::common::no_crash(&o, &format!("farm verify {args:?}"));
    assert!(!err.contains("internal error"), "{args:?}: {err}");
    assert!(
        t.elapsed() < Duration::from_secs(20),
        "{args:?}: {:?}",
        t.elapsed()
    );
    (o, err)
}

/// `farm verify` trusts nothing in a manifest (issue 42): a name leaving the batch directory
/// (`..`, absolute, a symbolic link) is refused naming the manifest, even with its true hash;
/// huge stated counts, a huge shard count in a file name or in `--shards` cost neither memory
/// nor time; a manifest that does not parse is named.
#[test]
fn verify_trusts_nothing_a_manifest_says() {
    let root = tempdir("farm-hostile-verify");
    let out = root.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let secret = root.join("secret.txt");
    std::fs::write(&secret, b"not the batch's").unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&secret, out.join("link.exr")).unwrap();
    let m = out.join("nsrm-farm.shard-0001-of-0001.json");
    let write = |v: &serde_json::Value| std::fs::write(&m, v.to_string()).unwrap();
    let abs = secret.to_str().unwrap().to_string();
    let mut names = vec!["../secret.txt".to_string(), abs];
    if cfg!(unix) {
        names.push("link.exr".into());
    }
    for name in &names {
        write(&hostile_manifest(name, b"not the batch's", 1.into()));
        let (o, err) = verify_bounded(&root, &["out"]);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains("FAILED"), "{name}: {err}");
        assert!(
            err.contains("nsrm-farm.shard-0001-of-0001.json"),
            "{name}: {err}"
        );
        assert!(err.contains("0 output(s) match"), "{name}: {err}");
    }
    // The same manifest naming a file of the batch is whole: the refusals above are the names'.
    std::fs::write(out.join("a.exr"), b"frame").unwrap();
    write(&hostile_manifest("a.exr", b"frame", 1.into()));
    let (o, err) = verify_bounded(&root, &["out"]);
    assert!(o.status.success(), "{err}");
    // Counts no file backs.
    for inputs in [
        serde_json::json!(1_000_000_000_000_000u64),
        serde_json::json!(u64::MAX),
        serde_json::json!(1e15),
    ] {
        write(&hostile_manifest("a.exr", b"frame", inputs.clone()));
        let (o, err) = verify_bounded(&root, &["out"]);
        assert_eq!(o.status.code(), Some(1), "{inputs}: {err}");
        assert!(
            err.contains("nsrm-farm.shard-0001-of-0001.json") || err.contains("input(s)"),
            "{inputs}: {err}"
        );
    }
    write(&hostile_manifest("a.exr", b"frame", 1.into()));
    std::fs::write(
        out.join("nsrm-farm.shard-0001-of-1000000000000.json"),
        b"{}",
    )
    .unwrap();
    let (o, err) = verify_bounded(&root, &["out"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("of-1000000000000.json"), "{err}");
    std::fs::remove_file(out.join("nsrm-farm.shard-0001-of-1000000000000.json")).unwrap();
    let (o, err) = verify_bounded(&root, &["out", "--shards", "1000000000000"]);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let (o, err) = verify_bounded(&root, &["out", "--shards", "100000"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("shards 1-100000/100000: no manifest"), "{err}");
    assert!(err.lines().count() < 10, "{err}");
    // A manifest that does not parse is named.
    std::fs::write(&m, b"{\"format\": ").unwrap();
    let (o, err) = verify_bounded(&root, &["out"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("out/nsrm-farm.shard-0001-of-0001.json: not a shard manifest"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&root);
}

/// The asset references Deadline Cloud's client (PyPI `deadline`) makes of the job bundle in
/// `dir`, as its submission does (the bundle's parameters, their values and
/// `asset_references.yaml`); `None` (SKIP) when the package is absent, a failure under CI.
fn deadline_asset_references(dir: &Path) -> Option<serde_json::Value> {
    let script = "import json, sys\n\
from deadline.client.job_bundle.parameters import read_job_bundle_parameters, apply_job_parameters\n\
from deadline.client.job_bundle.submission import AssetReferences\n\
from deadline.client.job_bundle.loader import read_yaml_or_json_object\n\
d = sys.argv[1]\n\
params = read_job_bundle_parameters(d)\n\
refs = AssetReferences.from_dict(read_yaml_or_json_object(d, 'asset_references', False))\n\
apply_job_parameters([], d, params, refs)\n\
print(json.dumps(refs.to_dict()))\n";
    let has = Command::new("python3")
        .args(["-c", "import deadline.client.job_bundle"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "PyPI deadline is missing under CI=true (.ci/install.d/50-farm.sh installs it)"
        );
        eprintln!("SKIP: PyPI deadline is not installed (.ci/install.d/50-farm.sh installs it)");
        return None;
    }
    let o = Command::new("python3")
        .args(["-c", script])
        .arg(dir)
        .output()
        .unwrap();
    assert_ok(&o);
    Some(serde_json::from_slice(&o.stdout).unwrap())
}

/// Names a template language or a YAML reader would misread (issue 42): Open Job Description
/// expressions and unmatched braces, a DEL, C1 controls, U+0085 and U+2028, shell syntax, a
/// leading dash.
const HOSTILE_NAMES: [&str; 6] = [
    "a{{Param.Model}}.exr",
    "b}}{{.exr",
    "c\u{7f}\u{85}\u{9b}\u{2028}é.exr",
    "d'$(touch x)`;.exr",
    "-e.exr",
    "f{{ Task.Param.Shard .exr",
];

/// The generated Open Job Description bundle carries hostile names to the worker byte for
/// byte: `openjd check` accepts it, `openjd run` runs it (with the whole tree moved and mapped)
/// with a stub program that records its argument vector and the input list it is given, and
/// the asset references read back (PyYAML, openjd's reader) exactly.
#[test]
fn openjd_hostile_names_reach_the_worker_byte_for_byte() {
    if !have("openjd") {
        return;
    }
    let root = tempdir("farm-openjd-hostile");
    let submit = root.join("sub {{Param.OutputDir}}");
    std::fs::create_dir_all(submit.join("in")).unwrap();
    for n in HOSTILE_NAMES {
        std::fs::write(submit.join("in").join(n), b"").unwrap();
    }
    let model = "m{{Task.Param.Shard}}}}.json";
    std::fs::write(submit.join(model), b"{}").unwrap();
    let record = root.join("argv.bin");
    let stub = root.join("stub.sh");
    std::fs::write(
        &stub,
        format!(
            "#!/bin/sh\nprev=\nfor a in \"$@\"; do\n  printf '%s\\0' \"$a\" >> '{r}'\n  if [ \"$prev\" = --inputs-from ]; then cat -- \"$a\" >> '{r}.list'; fi\n  prev=$a\ndone\nprintf 'END\\0' >> '{r}'\n",
            r = record.display()
        ),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&stub, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let out = "out {{Param.Shards}}";
    let made = nsrm_in(
        &submit,
        &[
            "farm",
            "openjd",
            "--shards",
            "2",
            "--job-dir",
            "job",
            "--program",
            stub.to_str().unwrap(),
            "--name",
            "hostile",
            "--device",
            "cpu",
            "--suffix",
            "_{{Param.Model}}",
            "--model",
            model,
            "-o",
            out,
            "in",
        ],
    );
    assert_ok(&made);
    let inputs: Vec<String> = {
        let mut v: Vec<String> = HOSTILE_NAMES
            .iter()
            .map(|n| submit.join("in").join(n).to_str().unwrap().to_string())
            .collect();
        v.sort();
        v
    };
    // The asset references as PyYAML (openjd's and deadline's reader) reads them.
    let refs = Command::new("python3")
        .arg("-c")
        .arg("import json,sys,yaml; print(json.dumps(yaml.safe_load(open(sys.argv[1], encoding='utf-8'))))")
        .arg(submit.join("job/asset_references.yaml"))
        .output()
        .unwrap();
    assert_ok(&refs);
    let refs: serde_json::Value = serde_json::from_slice(&refs.stdout).unwrap();
    let mut listed: Vec<String> = refs["assetReferences"]["inputs"]["filenames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    listed.sort();
    assert_eq!(listed, inputs);
    // Moved and mapped, as on a worker.
    let worker = root.join("worker }}");
    let rules = root.join("rules.json");
    let template = moved_to_worker(&submit, &worker, &rules);
    for step in ["Apply", "Verify"] {
        let o = Command::new("openjd")
            .arg("run")
            .arg(&template)
            .args(["--step", step, "-p"])
            .arg(format!(
                "file://{}",
                worker.join("job/job_parameters.json").display()
            ))
            .arg("--path-mapping-rules")
            .arg(format!("file://{}", rules.display()))
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{step}: {}{}",
            String::from_utf8_lossy(&o.stdout),
            stderr(&o)
        );
    }
    let bytes = std::fs::read(&record).unwrap();
    let words: Vec<&[u8]> = bytes
        .strip_suffix(b"\0")
        .unwrap_or(&bytes)
        .split(|&b| b == 0)
        .collect();
    let calls: Vec<&[&[u8]]> = words
        .split(|w| *w == b"END")
        .filter(|c| !c.is_empty())
        .collect();
    assert_eq!(calls.len(), 3, "{:?}", String::from_utf8_lossy(&bytes));
    let w = |s: &Path| s.to_str().unwrap().as_bytes().to_vec();
    let text = |c: &[&[u8]]| c.iter().map(|x| x.to_vec()).collect::<Vec<_>>();
    for (k, call) in calls[..2].iter().enumerate() {
        let call = text(call);
        let want_head: Vec<Vec<u8>> = vec![
            b"farm".to_vec(),
            b"run".to_vec(),
            b"--batch".to_vec(),
            b"hostile".to_vec(),
            b"--shard".to_vec(),
            format!("{}/2", k + 1).into_bytes(),
            b"--inputs-from".to_vec(),
            w(&worker.join("job/inputs.txt")),
            b"--path-mapping-rules".to_vec(),
        ];
        assert_eq!(call[..9], want_head[..], "{call:?}");
        let want_tail: Vec<Vec<u8>> = vec![
            b"--".to_vec(),
            b"--model".to_vec(),
            w(&worker.join(model)),
            b"-o".to_vec(),
            w(&worker.join(out)),
        ];
        assert_eq!(call[10..15], want_tail[..], "{call:?}");
        assert!(
            call.contains(&b"--suffix=_{{Param.Model}}".to_vec()),
            "{call:?}"
        );
    }
    assert_eq!(
        text(calls[2]),
        vec![
            b"farm".to_vec(),
            b"verify".to_vec(),
            w(&worker.join(out)),
            b"--shards".to_vec(),
            b"2".to_vec(),
            b"--model".to_vec(),
            w(&worker.join(model)),
        ]
    );
    // The input list each task is given: the submitter's paths, byte for byte (the task maps them).
    let mut want = Vec::new();
    for _ in 0..2 {
        let mut sorted = inputs.clone();
        sorted.sort();
        for i in &sorted {
            want.extend_from_slice(i.as_bytes());
            want.push(b'\n');
        }
    }
    let got = std::fs::read(root.join("argv.bin.list")).unwrap();
    let mut got_lines: Vec<&[u8]> = got
        .split(|&b| b == b'\n')
        .filter(|l| !l.is_empty())
        .collect();
    let mut want_lines: Vec<&[u8]> = want
        .split(|&b| b == b'\n')
        .filter(|l| !l.is_empty())
        .collect();
    got_lines.sort();
    want_lines.sort();
    assert_eq!(got_lines, want_lines);
    let _ = std::fs::remove_dir_all(&root);
}

/// A farm task opens the GPU (`--device auto`) with `XDG_RUNTIME_DIR` unset or naming no
/// directory, as under a batch scheduler: its log has no Mesa `XDG_RUNTIME_DIR` line.
#[test]
fn a_farm_task_log_has_no_mesa_runtime_dir_line() {
    let dir = tempdir("farm-xdg");
    batch(&dir, 2, 8, 8);
    for xdg in [None, Some("/nonexistent/nsrm-xdg")] {
        let mut c = crate::common::nsrm();
        c.current_dir(&dir).env_remove("XDG_RUNTIME_DIR");
        if let Some(x) = xdg {
            c.env("XDG_RUNTIME_DIR", x);
        }
        let o = c
            .args([
                "farm", "run", "--shard", "1/1", "--", "--model", "m.json", "-o", "out", "in",
            ])
            .output()
            .unwrap();
        let err = stderr(&o);
        assert!(o.status.success(), "{xdg:?}: {err}");
        assert!(
            !err.contains("XDG_RUNTIME_DIR"),
            "{xdg:?}: Mesa complained: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Moves a submitted bundle's tree from `submit` to `worker`, as a worker on other storage sees
/// it; checks its template with `openjd check`; writes path-mapping rules from `submit` to
/// `worker` into `rules`. The template's path.
fn moved_to_worker(submit: &Path, worker: &Path, rules: &Path) -> PathBuf {
    std::fs::rename(submit, worker).unwrap();
    let template = worker.join("job/template.yaml");
    let check = Command::new("openjd")
        .arg("check")
        .arg(&template)
        .output()
        .unwrap();
    assert_ok(&check);
    std::fs::write(
        rules,
        serde_json::json!({"version": "pathmapping-1.0", "path_mapping_rules": [
            {"source_path_format": "POSIX", "source_path": submit, "destination_path": worker}]})
        .to_string(),
    )
    .unwrap();
    template
}
