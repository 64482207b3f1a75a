//! The unit tests of `resources.rs` (moved beside it to keep the file short).

use super::*;

/// A value's YAML text, as the job files hold it.
fn yaml<T: serde::Serialize>(v: &T) -> String {
    crate::farmlib::yaml::to_string(v).unwrap()
}

/// The top-level keys of a mapping's YAML text, in order.
fn keys<T: serde::Serialize>(v: &T) -> Vec<String> {
    yaml(v)
        .lines()
        .filter(|l| !l.starts_with([' ', '-']))
        .map(|l| l.split(':').next().unwrap().to_string())
        .collect()
}

#[test]
fn memory_takes_slurm_units_and_is_bounded() {
    assert_eq!(parse_mem("8G").unwrap(), 8192);
    assert_eq!(parse_mem("1500").unwrap(), 1500);
    assert_eq!(parse_mem("1500M").unwrap(), 1500);
    assert_eq!(parse_mem("2Gi").unwrap(), 2048);
    assert_eq!(parse_mem("1tb").unwrap(), 1 << 20);
    assert_eq!(parse_mem("20000K").unwrap(), 20);
    for bad in [
        "",
        "G",
        "8X",
        "-1G",
        "1.5G",
        "8G;rm",
        "8 G\n",
        "15M",
        "65T",
        "999999999999999T",
    ] {
        assert!(parse_mem(bad).is_err(), "{bad:?}");
    }
}

#[test]
fn time_takes_slurm_forms_only() {
    for (s, want) in [
        ("30", 1800),
        ("30:15", 1815),
        ("2:00:00", 7200),
        ("1-0", 86400),
        ("1-2:30", 86400 + 9000),
        ("1-02:03:04", 86400 + 7384),
    ] {
        assert_eq!(parse_time(s).unwrap(), want, "{s}");
    }
    assert_eq!(slurm_time(86400 + 7384), "1-02:03:04");
    for bad in [
        "",
        "0",
        "1:2:3:4",
        "1-2:3:4:5",
        "a",
        "1h",
        "-5",
        "366-0",
        "1--2",
        "1:",
        ":1",
        "12;touch x",
        "9999999999",
    ] {
        assert!(parse_time(bad).is_err(), "{bad:?}");
    }
}

#[test]
fn sbatch_pass_through_is_one_safe_word() {
    assert_eq!(
        parse_sbatch_arg("--constraint=avx2").unwrap(),
        "--constraint=avx2"
    );
    assert_eq!(parse_sbatch_arg("--exclusive").unwrap(), "--exclusive");
    assert_eq!(
        parse_sbatch_arg("--comment=two words").unwrap(),
        "--comment=\"two words\""
    );
    for bad in [
        "-C avx2",
        "constraint=x",
        "--mem=4G",
        "--array=1-9",
        "--job-name=x",
        "--comment=a\"b",
        "--comment=a'b",
        "--comment=a\nset -x",
        "--Constraint=x",
        "--=x",
    ] {
        assert!(parse_sbatch_arg(bad).is_err(), "{bad:?}");
    }
    assert!(check_slurm_name("--partition", "gpu,cpu").is_ok());
    for bad in ["", "a b", "x\n#SBATCH --mem=1", "-x", &"p".repeat(65)] {
        assert!(check_slurm_name("--account", bad).is_err(), "{bad:?}");
    }
}

#[test]
fn kubernetes_names_labels_and_tolerations() {
    assert!(check_kube_name("nsrm-0123456789ab").is_ok());
    for bad in ["Plates", "a_b", "-a", "a-", "", "a.b", &"a".repeat(57)] {
        let e = check_kube_name(bad).unwrap_err().to_string();
        assert!(e.contains("RFC 1123 DNS label"), "{e}");
    }
    assert!(check_kube_name(&"a".repeat(56)).is_ok());
    assert_eq!(
        parse_node_selector("node.kubernetes.io/instance-type=g5.xlarge").unwrap(),
        (
            "node.kubernetes.io/instance-type".into(),
            "g5.xlarge".into()
        )
    );
    assert!(parse_node_selector("gpu=").is_ok());
    for bad in ["gpu", "=x", "a b=c", "k=v\nx: y", "k=-v", "Bad_Prefix/k=v"] {
        assert!(parse_node_selector(bad).is_err(), "{bad:?}");
    }
    assert_eq!(
        parse_toleration("nvidia.com/gpu:NoSchedule").unwrap(),
        Toleration {
            key: "nvidia.com/gpu".into(),
            value: None,
            effect: Some("NoSchedule".into())
        }
    );
    assert_eq!(
        parse_toleration("dedicated=render")
            .unwrap()
            .value
            .as_deref(),
        Some("render")
    );
    for bad in ["k:Never", "k=v:", "", "k=v w", "k=v:NoSchedule:x"] {
        assert!(parse_toleration(bad).is_err(), "{bad:?}");
    }
}

#[test]
fn openjd_host_requirements_follow_the_capability_names() {
    assert_eq!(
        parse_host_requirement("attr.worker.cpu.arch=x86_64").unwrap(),
        HostRequirement::Attr {
            name: "attr.worker.cpu.arch".into(),
            any_of: vec!["x86_64".into()]
        }
    );
    assert!(parse_host_requirement("amount.worker.gpu.memory=8192").is_ok());
    assert!(parse_host_requirement("attr.custom.site=paris,london").is_ok());
    assert!(parse_host_requirement("acme:amount.worker.licence=1").is_ok());
    for bad in [
        "amount.worker.vcpu=4",
        "amount.worker.foo=1",
        "attr.job.x=y",
        "amount.custom.x=-1",
        "amount.custom.x=inf",
        "attr.custom.x={{Param.Model}}",
        "custom.x=1",
        "attr.custom.x=",
    ] {
        assert!(parse_host_requirement(bad).is_err(), "{bad:?}");
    }
    assert!(check_os_family("Linux").is_ok() && check_os_family("beos").is_err());
}

#[test]
fn paths_outside_the_claim_are_named_with_the_fix() {
    assert_eq!(outside_mount("/data", &["/data/in/a.exr", "/data"]), None);
    let w = outside_mount(
        "/data/",
        &["/data/a.exr", "/database/b.exr", "/home/x/c.exr"],
    )
    .unwrap();
    assert!(
        w.contains("2 path(s)") && w.contains("/database/b.exr, /home/x/c.exr"),
        "{w}"
    );
    assert!(w.contains("--path-map /database=/data/…"), "{w}");
    let many: Vec<String> = (0..5).map(|i| format!("/x/{i}")).collect();
    let many: Vec<&str> = many.iter().map(String::as_str).collect();
    assert!(outside_mount("/data", &many)
        .unwrap()
        .contains("and 2 more"));
}

#[test]
fn headers_give_the_largest_frame_and_its_other_channels() {
    let dir = std::env::temp_dir().join(format!("nsrm-probe-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let small = dir.join("a.exr");
    let big = dir.join("b.exr");
    ::exr::prelude::write_rgb_file(&small, 8, 4, |_, _| (0.5f32, 0.5f32, 0.5f32)).unwrap();
    ::exr::prelude::write_rgba_file(&big, 16, 8, |_, _| (0.5f32, 0.5f32, 0.5f32, 1.0f32)).unwrap();
    let junk = dir.join("c.exr");
    std::fs::write(&junk, b"not a frame").unwrap();
    let p = probe_frames(&[small.clone(), junk, big], 16).unwrap();
    // The alpha (f32) is kept beside the camera RGB.
    assert_eq!((p.width, p.height, p.bytes), (16, 8, 16 * 8 * (12 + 4)));
    assert_eq!((p.probed, p.unread), (3, 1));
    let p = probe_frames(&[small], 16).unwrap();
    assert_eq!(p.bytes, 8 * 4 * 12);
    assert_eq!(probe_frames(&[dir.join("none.exr")], 16), None);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn memory_default_grows_with_frames_and_jobs() {
    let e = estimate_mem(4, 100 << 20);
    assert_eq!(e.mib, (BASE_MIB + 600) * 5 / 4);
    assert!(estimate_mem(8, 100 << 20).mib > e.mib);
    assert!(estimate_mem(4, 200 << 20).mib > e.mib);
    assert_eq!(estimate_mem(u32::MAX, u64::MAX).mib, MAX_MEM_MIB);
}

#[test]
fn each_engine_gets_what_was_asked() {
    let r = Resources {
        cpus: Some(4),
        mem_mib: Some(6000),
        time_s: Some(7200),
        gpus: 1,
        partition: Some("gpu".into()),
        account: None,
        qos: Some("high".into()),
        sbatch_args: vec!["--constraint=avx2".into()],
        node_selector: vec![("pool".into(), "render".into())],
        tolerations: vec![Toleration {
            key: "nvidia.com/gpu".into(),
            value: None,
            effect: Some("NoSchedule".into()),
        }],
        os_family: Some("linux".into()),
        host_requirements: Vec::new(),
        ..Resources::default()
    };
    let task = r.sbatch_lines(true);
    assert_eq!(
            task,
            "#SBATCH --partition=gpu\n#SBATCH --qos=high\n#SBATCH --cpus-per-task=4\n#SBATCH --mem=6000M\n#SBATCH --gpus=1\n#SBATCH --time=0-02:00:00\n#SBATCH --constraint=avx2\n"
        );
    let verify = r.sbatch_lines(false);
    assert!(verify.contains("--cpus-per-task=1\n") && !verify.contains("--gpus"));
    assert!(!verify.contains("--time") && verify.contains("--constraint=avx2"));
    assert_eq!(
        keys(&r.kube_pod_fields(false)),
        ["nodeSelector", "tolerations"]
    );
    let text = yaml(&r.openjd_host_requirements(true).unwrap());
    assert!(text.contains("amount.worker.gpu"), "{text}");
    assert!(text.contains("attr.worker.os.family"), "{text}");
    let k = yaml(&r.kube_resources(true).unwrap());
    assert!(k.contains("nvidia.com/gpu") && k.contains("6000Mi"), "{k}");
    assert_eq!(
        keys(&r.kube_pod_fields(true)),
        ["nodeSelector", "tolerations", "activeDeadlineSeconds"]
    );
    assert_eq!(
        yaml(&r.kube_pod_fields(true).tolerations),
        "- key: \"nvidia.com/gpu\"\n  operator: \"Exists\"\n  effect: \"NoSchedule\"\n"
    );
    assert_eq!(Resources::default().kube_resources(true), None);
    assert_eq!(Resources::default().openjd_host_requirements(true), None);
    assert_eq!(Resources::default().sbatch_lines(true), "");
    assert!(r
        .summary()
        .contains("4 CPU(s), 5.9 GiB memory, 1 GPU(s), time limit 0-02:00:00"));
}

#[test]
fn the_verification_has_its_own_time_limit() {
    let r = Resources {
        time_s: Some(7200),
        verify_time_s: Some(600),
        ..Resources::default()
    };
    assert!(r.sbatch_lines(true).contains("--time=0-02:00:00\n"));
    assert!(r.sbatch_lines(false).contains("--time=0-00:10:00\n"));
    let deadline = |task| r.kube_pod_fields(task).active_deadline_seconds;
    assert_eq!(deadline(true), Some(7200));
    assert_eq!(deadline(false), Some(600));
    assert_eq!(
        yaml(&r.kube_pod_fields(false)),
        "activeDeadlineSeconds: 600\n"
    );
    assert!(r.summary().contains("verification time limit 0-00:10:00"));
    let e = parse_time_for("--verify-time", "0")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("--verify-time \"0\""), "{e}");
}

#[test]
fn gpus_can_be_asked_for_by_another_resource_name() {
    for ok in [
        "amd.com/gpu",
        "gpu.intel.com/i915",
        "nvidia.com/mig-1g.10gb",
    ] {
        assert_eq!(check_gpu_resource(ok).unwrap(), ok);
    }
    for bad in [
        "gpu",
        "nvidia/gpu",
        "nvidia.com/",
        "/gpu",
        "Nvidia.com/gpu",
        "nvidia.com/gpu/x",
        "nvidia.com/-gpu",
        "kubernetes.io/gpu",
        "nvidia.com/gpu\ncpu: 1",
        "nvidia.com/gpu: 1",
    ] {
        assert!(check_gpu_resource(bad).is_err(), "{bad:?}");
    }
    let r = Resources {
        gpus: 2,
        gpu_resource: Some("amd.com/gpu".into()),
        ..Resources::default()
    };
    let k = yaml(&r.kube_resources(true).unwrap());
    assert!(
        k.contains("amd.com/gpu: \"2\"") && !k.contains("nvidia"),
        "{k}"
    );
    assert!(r.kube_resources(false).is_none());
}

#[test]
fn pod_spec_fields_pass_through_as_typed_values() {
    let args = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let f = parse_pod_fields(&args(&[
        r#"priorityClassName="render""#,
        r#"securityContext={"runAsUser":1000,"runAsNonRoot":true}"#,
        r#"imagePullSecrets=[{"name":"registry"}]"#,
    ]))
    .unwrap();
    assert_eq!(
        f[0],
        ("priorityClassName".into(), serde_json::json!("render"))
    );
    assert_eq!(
        f[1].1,
        serde_json::json!({"runAsNonRoot": true, "runAsUser": 1000})
    );
    let r = Resources {
        pod_fields: f,
        ..Resources::default()
    };
    assert_eq!(
        keys(&r.kube_pod_fields(true)),
        ["priorityClassName", "securityContext", "imagePullSecrets"]
    );
    // Typed as given: a number, a boolean, a string that looks like another type.
    assert_eq!(
        yaml(&r.kube_pod_fields(true)),
        "priorityClassName: \"render\"\nsecurityContext:\n  runAsNonRoot: true\n  runAsUser: 1000\nimagePullSecrets:\n  - name: \"registry\"\n"
    );
    for (bad, why) in [
        ("priorityClassName", "FIELD=JSON"),
        ("priorityClassName=render", "not JSON"),
        ("containers=[]", "nsrm writes containers itself"),
        ("tolerations=[]", "--toleration"),
        ("activeDeadlineSeconds=5", "--time"),
        ("Priority=\"x\"", "camelCase"),
        ("a-b=1", "camelCase"),
        ("x=null", "null"),
        ("x=1.5", "whole"),
        ("x={\"a\":null}", "null"),
    ] {
        let e = parse_pod_fields(&args(&[bad])).unwrap_err().to_string();
        assert!(e.contains(why), "{bad}: {e}");
    }
    let twice = parse_pod_fields(&args(&["x=1", "x=2"])).unwrap_err();
    assert!(twice.to_string().contains("twice"));
    let huge = format!("x=\"{}\"", "a".repeat(MAX_POD_FIELD_BYTES + 1));
    assert!(parse_pod_fields(&[huge])
        .unwrap_err()
        .to_string()
        .contains("KiB"));
    let deep = format!("x={}{}", "[".repeat(10_000), "]".repeat(10_000));
    assert!(parse_pod_fields(&[deep]).is_err());
}
