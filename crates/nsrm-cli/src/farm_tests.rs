//! The unit tests of `farm.rs` (moved beside it to keep the file short).

use super::*;

fn job(dir: &Path, name: &str) -> batch::Job {
    batch::Job {
        input: dir.join(format!("{name}.in.exr")),
        output: dir.join(format!("{name}.exr")),
        preview: None,
        action: batch::Action::Convert,
    }
}

#[test]
fn a_tasks_settings_are_parsed_once_and_kept_whole() {
    let words = [
        "--model",
        "m.json",
        "-o",
        "out",
        "--white",
        "5000",
        "--demosaic",
        "half",
        "--output-space",
        "acescg",
        "--",
        "a.exr",
        "-b.exr",
    ];
    let mut r = RunArgs {
        shard: "1/2".into(),
        inputs_from: None,
        path_map: Vec::new(),
        path_mapping_rules: None,
        batch: None,
        apply: words.iter().map(Into::into).collect(),
    };
    let mut a = shard_apply_args(&r).unwrap();
    // The settings the manifest records (and the job files carry) are the ones converted with.
    let s = a.settings_argv();
    assert!(
        s.contains(&"--white=5000".to_string())
            && s.contains(&"--demosaic=half".to_string())
            && s.windows(2).any(|w| w == ["--output-space", "acescg"])
            && s.contains(&"--continue-on-error".to_string()),
        "{s:?}"
    );
    let p = a.farm_parts();
    assert!(*p.continue_on_error && !p.overwrite);
    // The inputs come after `--`, so one that starts with `-` is an input.
    assert_eq!(*p.inputs, [PathBuf::from("a.exr"), PathBuf::from("-b.exr")]);
    // Replacing is the task's to decide.
    r.apply.insert(0, "--overwrite".into());
    assert!(shard_apply_args(&r).is_err());
}

#[test]
fn stale_temporaries_of_other_shards_are_left_alone() {
    let dir = std::env::temp_dir().join(format!("house2-farm-stale-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mine = dir.join(".a.exr.nsrm-tmp-1");
    let theirs = dir.join(".b.exr.nsrm-tmp-2");
    for p in [&mine, &theirs] {
        std::fs::write(p, b"x").unwrap();
    }
    let plan = batch::BatchPlan {
        jobs: vec![job(&dir, "a")],
        total_inputs: 2,
        shard: None,
        dirs: vec![dir.clone()],
    };
    let stale = [mine.clone(), theirs.clone()];
    assert_eq!(
        remove_stale_temporaries(&plan, &stale),
        [".a.exr.nsrm-tmp-1"]
    );
    assert!(!mine.exists() && theirs.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_missing_output_is_recorded_as_a_failure_and_counted() {
    let dir = std::env::temp_dir().join(format!("house2-farm-rec-{}", std::process::id()));
    let (outputs, failures) = record(&[job(&dir, "gone")], vec![Found::Todo(false)]);
    assert!(outputs.is_empty());
    assert_eq!(failures.len(), 1);
    assert_eq!(failures[0].output, "gone.exr");
    assert!(failures[0].why.contains("no output"), "{}", failures[0].why);
    let m = ShardManifest {
        format: manifest::FORMAT.into(),
        nsrm_version: "0".into(),
        shard: 2,
        shards: 3,
        batch: Batch::of(&["gone.exr".to_string()]),
        model: ModelRecord {
            path: "m.json".into(),
            sha256: String::new(),
        },
        settings: Vec::new(),
        outputs,
        failures,
        stale_temporaries_removed: vec!["x".into()],
        timings: manifest::Timings {
            started_unix: 0.0,
            check_s: 0.0,
            convert_s: 0.0,
            hash_s: 0.0,
            total_s: 1.5,
        },
    };
    let shard = Shard { index: 2, count: 3 };
    let line = shard_summary(shard, &m, Path::new("m.json"));
    assert!(
        line.contains("0 converted, 0 replaced, 0 kept, 0 adopted"),
        "{line}"
    );
    assert!(
        line.contains("1 failed; 1 stale temporary removed; 1.50 s"),
        "{line}"
    );
}

#[test]
fn batch_names_are_stable_and_differ_between_batches() {
    let i = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let a = batch_name(&i(&["/a.exr", "/b.exr"]), "/m", "/o", 2, &[]);
    assert_eq!(a, batch_name(&i(&["/a.exr", "/b.exr"]), "/m", "/o", 2, &[]));
    assert!(a.starts_with("nsrm-") && a.len() == 17, "{a}");
    for other in [
        batch_name(&i(&["/a.exr"]), "/m", "/o", 2, &[]),
        batch_name(&i(&["/a.exr", "/b.exr"]), "/m2", "/o", 2, &[]),
        batch_name(&i(&["/a.exr", "/b.exr"]), "/m", "/o2", 2, &[]),
        batch_name(&i(&["/a.exr", "/b.exr"]), "/m", "/o", 3, &[]),
        batch_name(&i(&["/a.exr", "/b.exr"]), "/m", "/o", 2, &i(&["--half"])),
        batch_name(&i(&["/a.exr/b.exr"]), "/m", "/o", 2, &[]),
    ] {
        assert_ne!(a, other);
    }
}

#[test]
fn a_shards_command_carries_the_rules_only_for_openjd() {
    let lit = |s: &str| Arg::Lit(s.to_string());
    let settings = vec!["--output-space".to_string(), "acescg".to_string()];
    let slurm = task_args(false, Some("/p"), &settings);
    assert_eq!(
        slurm,
        [
            lit("farm"),
            lit("run"),
            lit("--shard"),
            Arg::Shard,
            lit("--inputs-from"),
            Arg::InputList,
            lit("--"),
            lit("--model"),
            Arg::Model,
            lit("-o"),
            Arg::OutputDir,
            lit("--preview"),
            lit("/p"),
            lit("--output-space"),
            lit("acescg"),
        ]
    );
    let openjd = task_args(true, None, &[]);
    assert_eq!(
        &openjd[6..8],
        &[lit("--path-mapping-rules"), Arg::PathMappingRules]
    );
    assert_eq!(openjd.len(), 13);
    assert!(verify_args(false, None).contains(&Arg::Shards));
    let v = verify_args(true, Some("/p"));
    assert!(v.ends_with(&[
        lit("--preview"),
        lit("/p"),
        lit("--path-mapping-rules"),
        Arg::PathMappingRules
    ]));
}
