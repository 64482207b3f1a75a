//! The unit tests of `jobs.rs` (moved beside it to keep the file short).

use super::*;

fn spec() -> JobSpec {
    JobSpec {
        name: "plates".into(),
        shards: 3,
        inputs: vec!["/in/a b.exr".into(), "/in/it's.exr".into()],
        model: "/m/model.json".into(),
        output_dir: "/out".into(),
        preview_dir: None,
        job_dir: "/job".into(),
        program: "nsrm".into(),
        task: vec![
            Arg::Lit("farm".into()),
            Arg::Shard,
            Arg::InputList,
            Arg::Model,
            Arg::OutputDir,
        ],
        verify: vec![Arg::Lit("verify".into()), Arg::OutputDir, Arg::Shards],
        resources: Default::default(),
        batch: "nsrm-0123456789ab".into(),
    }
}

#[test]
fn shell_words_survive_quotes_and_spaces() {
    assert_eq!(sh_quote("plain/path.exr"), "plain/path.exr");
    assert_eq!(sh_quote("a b"), "'a b'");
    assert_eq!(sh_quote("it's"), r"'it'\''s'");
    assert_eq!(sh_quote(""), "''");
    let files = slurm(&spec()).unwrap();
    let array = &files[0].text;
    assert!(array.contains("#SBATCH -a 1-3\n"), "{array}");
    assert!(
            array.contains("exec nsrm farm \"$SLURM_ARRAY_TASK_ID/3\" - /m/model.json /out <<'NSRM_INPUTS_END'\n/in/a b.exr\n/in/it's.exr\nNSRM_INPUTS_END\n"),
            "{array}"
        );
    assert!(files[1].text.contains("exec nsrm verify /out 3\n"));
}

#[test]
fn the_here_document_delimiter_is_no_input_line() {
    let mut s = spec();
    s.inputs.push("NSRM_INPUTS_END".into());
    let array = &slurm(&s).unwrap()[0].text;
    assert!(array.contains("<<'NSRM_INPUTS_END_'\n"), "{array}");
}

#[test]
fn what_no_job_can_carry_is_refused() {
    let mut s = spec();
    s.inputs.push("/in/new\nline.exr".into());
    assert!(openjd(&s).unwrap_err().is_usage());
    let mut s = spec();
    s.shards = 0;
    assert!(slurm(&s).unwrap_err().is_usage());
    let mut s = spec();
    s.task
        .push(Arg::Lit("x".repeat(OPENJD_MAX_STRING + 1) + "{{"));
    assert!(openjd(&s).unwrap_err().is_usage());
    let mut s = spec();
    s.task.push(Arg::PathMappingRules);
    assert!(slurm(&s).unwrap_err().is_usage());
    let mut s = spec();
    s.name = "two words".into();
    assert!(openjd(&s).unwrap_err().is_usage());
}

/// A document as JSON, to look into (serde_json's objects sort their keys; the YAML text keeps
/// the fields' order).
fn value<T: serde::Serialize>(doc: &T) -> serde_json::Value {
    serde_json::to_value(doc).unwrap()
}

fn kube_place() -> Kube {
    Kube {
        image: "nsrm:1".into(),
        claim: "plates".into(),
        mount_path: "/data".into(),
        parallelism: 8,
        retries_per_index: 2,
    }
}

#[test]
fn template_words_reach_openjd_workers_as_parameter_values() {
    let mut s = spec();
    let hostile = ["a{{Param.Model}}", "}}", "{{", "{{Task.Param.Shard}}/x"];
    s.task
        .extend(hostile.iter().map(|h| Arg::Lit(h.to_string())));
    s.verify.push(Arg::Lit(hostile[0].into()));
    let literals = openjd_literals(&s).unwrap();
    assert_eq!(literals, hostile);
    let files = openjd(&s).unwrap();
    let template = &files[0].text;
    // Every `{{` of the template's format strings (all but the parameters' default
    // values, which are not templates) opens one of the engine's own names.
    let formats: String = template
        .lines()
        .filter(|l| !l.trim_start().starts_with("default:"))
        .collect();
    for (i, _) in formats.match_indices("{{") {
        let rest = &formats[i + 2..];
        assert!(
            ["Param.", "Task.Param.", "Session."]
                .iter()
                .any(|p| rest.starts_with(p)),
            "{}",
            &formats[i..]
        );
    }
    for (i, h) in hostile.iter().enumerate() {
        assert!(
            template.contains(&format!("\"{{{{Param.NsrmArg{}}}}}\"", i + 1)),
            "{h}: {template}"
        );
    }
    assert_eq!(files[3].name, OPENJD_INPUT_LIST);
    assert_eq!(files[3].text, s.input_list());
    let refs = value(&openjd_asset_references(&s));
    assert_eq!(
        refs["assetReferences"]["inputs"]["filenames"],
        serde_json::json!(s.inputs)
    );
}

#[test]
fn openjd_parameters_values_and_actions() {
    let s = spec();
    let params = openjd_parameters(&s, &[]);
    let named: Vec<(&str, &str)> = params.iter().map(|p| (p.name.as_str(), p.ty)).collect();
    assert_eq!(
        named,
        [
            ("Shards", "INT"),
            ("InputList", "PATH"),
            ("Model", "PATH"),
            ("OutputDir", "PATH"),
            ("NsrmProgram", "STRING"),
        ]
    );
    assert_eq!(params[0].default, Some(OpenjdDefault::Int(3)));
    assert_eq!(value(&params)[0]["default"], 3);
    let (yaml_values, json) = openjd_values(&s);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["Shards"], "3");
    assert_eq!(v["OutputDir"], "/out");
    assert_eq!(v["InputList"], "/job/inputs.txt");
    assert_eq!(yaml_values.parameter_values.len(), 5);
    let action = value(&openjd_action(&s.verify, &[], None));
    assert_eq!(
        action["actions"]["onRun"]["args"],
        serde_json::json!(["verify", "{{Param.OutputDir}}", "{{Param.Shards}}"])
    );
    assert!(action["actions"]["onRun"]["timeout"].is_null());
    let steps = value(&openjd_steps(&s, &[]));
    assert_eq!(steps[1]["name"], "Verify");
    assert_eq!(steps[1]["dependencies"][0]["dependsOn"], "Apply");
    // No resources asked: no host requirements, no dependencies of the first step.
    assert!(steps[0].get("hostRequirements").is_none() && steps[0].get("dependencies").is_none());
}

/// `wait.sh` returns on `Failed` as on `Complete` and says which (a stub `kubectl` reports
/// the Job's true conditions).
#[cfg(unix)]
#[test]
fn the_kubernetes_wait_returns_on_failed_and_on_complete() {
    let dir = std::env::temp_dir().join(format!("nsrm-kube-wait-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let script = dir.join("wait.sh");
    std::fs::write(&script, kube_wait_script("plates")).unwrap();
    for (state, code, said) in [
        ("Failed", 1, "job/plates: Failed"),
        ("SuccessCriteriaMet Complete", 0, "job/plates: Complete"),
    ] {
        let kubectl = dir.join("kubectl");
        std::fs::write(&kubectl, format!("#!/bin/sh\nprintf '%s' '{state}'\n")).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&kubectl, std::fs::Permissions::from_mode(0o755)).unwrap();
        let path = format!(
            "{}:{}",
            dir.display(),
            std::env::var("PATH").unwrap_or_default()
        );
        let o = std::process::Command::new("sh")
            .arg(&script)
            .env("PATH", path)
            .output()
            .unwrap();
        let text =
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{state}: {text}");
        assert!(text.contains(said), "{state}: {text}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn kubernetes_pods_mount_the_claim_and_the_shards_the_list() {
    let (s, k) = (spec(), kube_place());
    let (mounts, volumes) = kube_volumes(&s, &k, true);
    assert_eq!(mounts.len(), 2);
    assert_eq!(value(&volumes)[1]["configMap"]["name"], "plates-inputs");
    assert_eq!(
        value(&volumes)[0]["persistentVolumeClaim"]["claimName"],
        "plates"
    );
    let (mounts, volumes) = kube_volumes(&s, &k, false);
    assert_eq!((mounts.len(), volumes.len()), (1, 1));
    let job = value(&kube_indexed_job(&s, &k, "true"));
    assert_eq!(job["spec"]["parallelism"], 3);
    assert_eq!(job["spec"]["completions"], 3);
    assert_eq!(job["spec"]["ttlSecondsAfterFinished"], KUBE_TTL_S);
    assert!(job["spec"].get("backoffLimit").is_none());
    let verify = value(&kube_verify_job(&s, &k, "exec x"));
    assert_eq!(verify["metadata"]["name"], "plates-verify");
    assert_eq!(verify["spec"]["backoffLimit"], 0);
    assert!(verify["spec"].get("completionMode").is_none());
    assert_eq!(
        value(&kube_config_map(&s))["data"],
        serde_json::json!({"inputs.txt": "/in/a b.exr\n/in/it's.exr\n"})
    );
    // The YAML keeps the fields' order: a Kubernetes object starts with its kind.
    let text = yaml::to_string(&kube_verify_job(&s, &k, "exec x")).unwrap();
    assert!(
        text.starts_with(
            "apiVersion: \"batch/v1\"\nkind: \"Job\"\nmetadata:\n  name: \"plates-verify\"\n"
        ),
        "{text}"
    );
    let pod = text.split("    spec:\n").nth(1).unwrap();
    assert!(
        pod.starts_with("      restartPolicy: \"Never\"\n      containers:\n"),
        "{text}"
    );
}
