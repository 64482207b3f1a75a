//! The unit tests of `batch.rs` (moved beside it to keep the file short).

use super::*;

#[test]
fn shard_parse_and_partition() {
    assert_eq!(Shard::parse("2/3").unwrap(), Shard { index: 2, count: 3 });
    for bad in ["0/3", "4/3", "1/0", "x/2", "3", "1/y", ""] {
        assert!(Shard::parse(bad).is_err(), "{bad}");
    }
    let items: Vec<usize> = (0..10).collect();
    let mut all: Vec<usize> = (1..=3)
        .flat_map(|k| Shard { index: k, count: 3 }.select(&items))
        .collect();
    all.sort();
    assert_eq!(all, items);
    assert_eq!(
        Shard { index: 1, count: 3 }.select(&items),
        vec![0, 3, 6, 9]
    );
}

#[test]
fn output_names_keep_frame_numbers() {
    let f = FileFormat::Exr;
    assert_eq!(
        output_path(Path::new("a/plate.0101.exr"), None, "_xyz", f),
        Path::new("a/plate_xyz.0101.exr")
    );
    assert_eq!(
        output_path(
            Path::new("a/shot.tif"),
            Some(Path::new("out")),
            "_acescg",
            f
        ),
        Path::new("out/shot_acescg.exr")
    );
    assert_eq!(
        output_path(Path::new("v1.2.exr"), None, "_x", FileFormat::Tiff),
        Path::new("v1_x.2.tif")
    );
    assert_eq!(
        output_path(Path::new("take.final.exr"), None, "_x", f),
        Path::new("take.final_x.exr")
    );
}

fn opts(suffix: &str) -> PlanOptions<'_> {
    PlanOptions {
        suffix,
        create_dirs: true,
        ..Default::default()
    }
}

#[test]
fn plan_refuses_collisions() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.exr");
    let b = dir.path().join("a.tif");
    std::fs::write(&a, b"x").unwrap();
    std::fs::write(&b, b"x").unwrap();
    let e = plan_batch(&[a.clone(), b], &opts("_xyz")).unwrap_err();
    assert!(e.to_string().contains("would both be written"), "{e}");
    let e = plan_batch(std::slice::from_ref(&a), &opts("")).unwrap_err();
    assert!(e.to_string().contains("onto that input itself"), "{e}");
    let p = plan_batch(std::slice::from_ref(&a), &opts("_xyz")).unwrap();
    assert_eq!(p.jobs[0].output, dir.path().join("a_xyz.exr"));
    assert_eq!(p.jobs[0].action, Action::Convert);
}

#[test]
fn suffixes_are_name_fragments() {
    for bad in ["/x", "a/b", "..", "_..", "a\\b"] {
        assert!(validate_suffix(bad).is_err(), "{bad}");
    }
    for good in ["", "_xyz", ".v2", "-final"] {
        validate_suffix(good).unwrap();
    }
}

#[test]
fn outputs_are_compared_after_resolving_dirs_and_links() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = d.join("a.exr");
    std::fs::write(&a, b"x").unwrap();
    // -o through a directory that does not exist yet, back up with `..`.
    let through = d.join("newdir/..");
    let o = PlanOptions {
        out_dir: Some(&through),
        ..opts("")
    };
    let e = plan_batch(std::slice::from_ref(&a), &o).unwrap_err();
    assert!(e.to_string().contains("onto that input itself"), "{e}");
    // A dry run (no directories made) sees the same.
    let o = PlanOptions {
        create_dirs: false,
        out_dir: Some(Path::new("/nonexistent-nsrm/zz/..")),
        ..opts("")
    };
    plan_batch(std::slice::from_ref(&a), &o).unwrap();
    #[cfg(unix)]
    {
        // An existing output that is a hard link or a symlink to an input.
        let out = d.join("out");
        std::fs::create_dir(&out).unwrap();
        std::fs::hard_link(&a, out.join("a.exr")).unwrap();
        let o = PlanOptions {
            out_dir: Some(&out),
            existing: Existing::Overwrite,
            ..opts("")
        };
        let e = plan_batch(std::slice::from_ref(&a), &o).unwrap_err();
        assert!(e.to_string().contains("onto that input itself"), "{e}");
        std::fs::remove_file(out.join("a.exr")).unwrap();
        std::os::unix::fs::symlink(&a, out.join("a.exr")).unwrap();
        let e = plan_batch(std::slice::from_ref(&a), &o).unwrap_err();
        assert!(e.to_string().contains("onto that input itself"), "{e}");
        // A preview directory that is the inputs' directory cannot hit an input (.png),
        // but a symlinked preview name can.
        std::fs::remove_file(out.join("a.exr")).unwrap();
        std::os::unix::fs::symlink(&a, out.join("a.png")).unwrap();
        let o = PlanOptions {
            out_dir: Some(&out),
            preview_dir: Some(&out),
            existing: Existing::Overwrite,
            ..opts("")
        };
        let e = plan_batch(std::slice::from_ref(&a), &o).unwrap_err();
        assert!(e.to_string().contains("the preview for"), "{e}");
    }
}

#[test]
fn existing_outputs_follow_the_policy_and_non_files_always_fail() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = d.join("a.exr");
    std::fs::write(&a, b"x").unwrap();
    std::fs::write(d.join("a_x.exr"), b"old").unwrap();
    let run = |existing| {
        let o = PlanOptions {
            existing,
            ..opts("_x")
        };
        plan_batch(std::slice::from_ref(&a), &o).unwrap().jobs[0]
            .action
            .clone()
    };
    assert!(matches!(run(Existing::Refuse), Action::Fail(_)));
    assert!(matches!(run(Existing::Skip), Action::Skip(_)));
    assert_eq!(run(Existing::Overwrite), Action::Convert);
    std::fs::remove_file(d.join("a_x.exr")).unwrap();
    std::fs::create_dir(d.join("a_x.exr")).unwrap();
    match run(Existing::Overwrite) {
        Action::Fail(why) => assert!(
            why.to_string()
                .contains("not a regular file (it is a directory)"),
            "{why}"
        ),
        other => panic!("{other:?}"),
    }
}

#[cfg(unix)]
#[test]
fn non_utf8_names_are_kept() {
    use std::os::unix::ffi::OsStrExt;
    let name = std::ffi::OsStr::from_bytes(b"pl\xffte.0101.exr");
    let out = output_path(Path::new(name), None, "_x", FileFormat::Exr);
    assert_eq!(out.as_os_str().as_bytes(), b"pl\xffte_x.0101.exr");
    let out = output_path(
        Path::new(std::ffi::OsStr::from_bytes(b"\xff.exr")),
        None,
        "_x",
        FileFormat::Tiff,
    );
    assert_eq!(out.as_os_str().as_bytes(), b"\xff_x.tif");
}

#[test]
fn glob_components_match_bytes() {
    let p = |s: &str| Pattern::parse(s.as_bytes()).unwrap();
    assert!(p("*.exr").matches(b"a.exr"));
    assert!(!p("*.exr").matches(b".a.exr"));
    assert!(p(".*").matches(b".a"));
    assert!(p("pl?te").matches("pläte".as_bytes()));
    assert!(p("pl?te").matches(b"pl\xe9te"));
    assert!(p("pl*").matches(b"pl\xe9te\xff"));
    assert!(p("[!a]x").matches(b"\xffx"));
    assert!(!p("[a-z]x").matches(b"\xffx"));
    assert!(p("f.[0-9][0-9]*").matches(b"f.0123.exr"));
    assert!(!p("f.[0-9][0-9]*").matches(b"f.a123.exr"));
    assert!(p("[]]").matches(b"]"));
    assert!(p("a*b*c").matches(b"aXbYbZc"));
    assert!(!p("a*b*c").matches(b"aXbYbZ"));
    assert!(Pattern::parse(b"[abc").is_err());
    assert!(Pattern::parse(b"[z-a]").is_err());
    // A non-UTF-8 byte in the pattern matches the same byte.
    let q = Pattern::parse(b"pl\xe9*").unwrap();
    assert!(q.matches(b"pl\xe9te.exr") && !q.matches("plé".as_bytes()));
}

#[cfg(unix)]
#[test]
fn double_star_walks_sorted_and_does_not_follow_links() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    for d in ["b/c", "a", ".h/x"] {
        std::fs::create_dir_all(root.join(d)).unwrap();
    }
    // A loop: b/c/up → the root.
    std::os::unix::fs::symlink(root, root.join("b/c/up")).unwrap();
    let mut out = Vec::new();
    walk_dirs(root, &mut out).unwrap();
    let rel: Vec<_> = out
        .iter()
        .map(|p| p.strip_prefix(root).unwrap().to_path_buf())
        .collect();
    let want: Vec<PathBuf> = ["", "a", "b", "b/c"].iter().map(PathBuf::from).collect();
    assert_eq!(rel, want);
}

#[cfg(unix)]
#[test]
fn globs_keep_non_utf8_directory_names() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let odd = root.join(OsStr::from_bytes(b"pl\xe9te"));
    let plain = root.join("plain");
    let hidden = root.join(".hidden");
    let deep = plain.join("sub");
    for d in [&odd, &plain, &hidden, &deep] {
        std::fs::create_dir_all(d).unwrap();
    }
    let files = [
        odd.join("a.exr"),
        odd.join(OsStr::from_bytes(b"\xff.exr")),
        plain.join("b.exr"),
        hidden.join("c.exr"),
        deep.join("d.tif"),
    ];
    for f in &files {
        std::fs::write(f, b"x").unwrap();
    }
    std::fs::write(plain.join("notes.txt"), b"x").unwrap();
    let expand = |pat: &[u8]| {
        let mut spec = root.as_os_str().as_bytes().to_vec();
        spec.push(b'/');
        spec.extend_from_slice(pat);
        expand_inputs(&[OsStr::from_bytes(&spec)])
    };
    let got = expand(b"*/*.exr").unwrap();
    let mut want = vec![files[0].clone(), files[1].clone(), files[2].clone()];
    want.sort();
    assert_eq!(got, want);
    // A non-UTF-8 pattern, wildcards in both parts.
    assert_eq!(
        expand(b"pl\xe9*/?.exr").unwrap(),
        vec![files[0].clone(), files[1].clone()]
    );
    assert_eq!(expand(b"pl?te/\xff.*").unwrap(), vec![files[1].clone()]);
    // `**`: every depth, hidden directories left out.
    let got = expand(b"**/*.tif").unwrap();
    assert_eq!(got, vec![files[4].clone()]);
    assert_eq!(expand(b"**/*.exr").unwrap().len(), 3);
    let e = expand(b"*/*.png").unwrap_err().to_string();
    assert!(e.contains("matches no"), "{e}");
    let e = expand(b"*/[ab.exr").unwrap_err().to_string();
    assert!(e.contains("bad pattern"), "{e}");
    // A relative pattern keeps its form (no `./` added).
    let rel = Path::new("src/*.rs");
    let mut v = Vec::new();
    glob_into(rel.as_os_str(), &mut v).unwrap();
    assert!(v.is_empty(), "not frames: {v:?}");
}

/// Cases per property: `NSRM_FUZZ_CASES` when set (as in `tests/all/harden_fuzz.rs`).
fn fuzz_cases(default: u32) -> u32 {
    std::env::var("NSRM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

// Property-based fuzzing of the flag parsers (moved from `tests/all/harden_fuzz.rs` when the
// batch plan became crate-private): any string is parsed or refused, never a panic, and
// whatever is accepted is well formed.
proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig {
        cases: fuzz_cases(2000),
        ..proptest::prelude::ProptestConfig::default()
    })]

    #[test]
    fn shard_specs_parse_or_refuse(spec in "[0-9/ x-]{0,30}|\\PC{0,20}") {
        if let Ok(s) = Shard::parse(&spec) {
            proptest::prop_assert!(s.index >= 1 && s.index <= s.count);
            proptest::prop_assert!(s.contains(s.index - 1));
        }
    }

    #[test]
    fn suffixes_and_names_never_escape(suffix in "\\PC{0,12}", stem in "[a-z0-9.]{0,12}") {
        if validate_suffix(&suffix).is_ok() {
            let input = Path::new("dir").join(format!("{stem}.exr"));
            let out = output_path(&input, None, &suffix, FileFormat::Exr);
            proptest::prop_assert_eq!(out.parent(), Some(Path::new("dir")));
        }
    }
}
