//! The session's tests: clobbering, temporaries, units, inputs against outputs, and the
//! session as a batch's sink.

use super::*;

fn leftovers(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".tmp")
        })
        .count()
}

#[test]
fn refuses_to_clobber_and_leaves_no_temp() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let f = dir.join("a.json");
    Session::new(false).write_bytes(&f, b"one").unwrap();
    let e = Session::new(false).write_bytes(&f, b"two").unwrap_err();
    assert!(matches!(e, WriteError::Exists(_)));
    assert_eq!(std::fs::read(&f).unwrap(), b"one");
    Session::new(true).write_bytes(&f, b"two").unwrap();
    assert_eq!(std::fs::read(&f).unwrap(), b"two");
    assert_eq!(leftovers(dir), 0);
    let e = Session::new(false)
        .write_bytes(&dir.join("no/such/dir/x"), b"x")
        .unwrap_err();
    assert!(e.to_string().contains("cannot write"));
    // A directory is never replaced, even with overwrite.
    std::fs::create_dir(dir.join("d")).unwrap();
    let e = Session::new(true)
        .write_bytes(&dir.join("d"), b"x")
        .unwrap_err();
    assert!(
        e.to_string()
            .contains("not a regular file (it is a directory)"),
        "{e}"
    );
}

#[test]
fn temp_names_are_unique_and_recognised() {
    let dir = tempfile::tempdir().unwrap();
    let dest = dir.path().join("x.exr");
    let (_, a) = make_temp(&dest, |p| File::create_new(p)).unwrap();
    let (_, b) = make_temp(&dest, |p| File::create_new(p)).unwrap();
    assert_ne!(a, b);
    assert!(a.exists() && b.exists());
    assert!(is_temp_name(a.file_name().unwrap()), "{a:?}");
    assert!(a.starts_with(dir.path()), "{a:?}");
    assert!(
        a.file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with(".x.exr.nsrm-"),
        "{a:?}"
    );
    // A taken name is never opened: `make` sees AlreadyExists and another name is drawn.
    let mut tries = 0;
    let (_, c) = make_temp(&dest, |p| {
        tries += 1;
        if tries == 1 {
            File::create_new(&a)
        } else {
            File::create_new(p)
        }
    })
    .unwrap();
    assert!(tries == 2 && c != a);
    for bad in [
        "x.tmp",
        ".x.nsrm-1-abc.tmp",
        ".x.nsrm--0123456789abcdef.tmp",
        ".x.nsrm-1-0123456789abcde_.tmp",
        ".nsrm-1-0123456789abcdef.tmp",
    ] {
        assert!(!is_temp_name(OsStr::new(bad)), "{bad}");
    }
    assert!(is_temp_name(OsStr::new(
        ".x.exr.nsrm-1-0123456789abcdef.tmp"
    )));
}

#[test]
fn a_dropped_unit_removes_only_its_own_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let dest = dir.path().join("x.bin");
    // Someone else's file that looks like a temporary is never touched.
    let other = dir.path().join(".x.bin.nsrm-1-0123456789abcdef.tmp");
    std::fs::write(&other, b"theirs").unwrap();
    let session = Session::new(false);
    let mut unit = session.unit();
    unit.write_bytes(&dest, b"mine").unwrap();
    assert_eq!(session.temporaries_held(), 1);
    assert_eq!(stale_temporaries(dir.path()).len(), 2);
    drop(unit);
    assert_eq!(session.temporaries_held(), 0);
    assert!(!dest.exists());
    assert_eq!(std::fs::read(&other).unwrap(), b"theirs");
    assert_eq!(stale_temporaries(dir.path()), vec![other]);
}

#[test]
fn a_failing_encoder_leaves_nothing_behind() {
    // A write failure (disk full, an encoder error) half-way through: simulated by the
    // encoder, since a full filesystem cannot be made in CI.
    let dir = tempfile::tempdir().unwrap();
    let dest = dir.path().join("x.exr");
    let session = Session::new(false);
    let mut unit = session.unit();
    let r: Result<(), WriteError> = unit.write_with(&dest, |w| {
        w.write_all(&[0u8; 100_000]).unwrap();
        Err(WriteError::Io {
            path: dest.clone(),
            err: std::io::Error::new(std::io::ErrorKind::StorageFull, "no space left"),
        })
    });
    assert!(r.unwrap_err().to_string().contains("no space left"));
    assert!(unit.is_empty());
    unit.commit().unwrap();
    assert!(!dest.exists());
    assert_eq!(leftovers(dir.path()), 0);
}

#[test]
fn a_unit_places_all_or_none_and_restores_what_it_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let (a, c) = (dir.path().join("a"), dir.path().join("c"));
    let session = Session::new(false);
    let mut unit = session.unit();
    unit.write_bytes(&a, b"1").unwrap();
    unit.write_bytes(&c, b"2").unwrap();
    // a appears before the commit: c is not placed either.
    std::fs::write(&a, b"raced").unwrap();
    assert!(matches!(unit.commit(), Err(WriteError::Exists(_))));
    assert!(!c.exists());
    assert_eq!(std::fs::read(&a).unwrap(), b"raced");
    assert_eq!(leftovers(dir.path()), 0);
    // With overwrite: the first is replaced, the second fails (a directory appeared), the
    // first's old content comes back.
    let session = Session::new(true);
    let mut unit = session.unit();
    unit.write_bytes(&a, b"new").unwrap();
    unit.write_bytes(&c, b"2").unwrap();
    std::fs::create_dir(&c).unwrap();
    assert!(unit.commit().is_err());
    assert_eq!(std::fs::read(&a).unwrap(), b"raced");
    assert_eq!(leftovers(dir.path()), 0);
    assert_eq!(session.temporaries_held(), 0);
}

#[test]
fn outputs_are_checked_against_inputs_and_each_other() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = d.join("in.exr");
    std::fs::write(&input, b"x").unwrap();
    std::fs::create_dir(d.join("sub")).unwrap();
    std::fs::hard_link(&input, d.join("link.exr")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&input, d.join("sym.exr")).unwrap();
    let mut s = Session::new(true);
    s.input(&input).unwrap();
    for bad in [
        input.clone(),
        d.join("sub/../in.exr"),
        d.join("link.exr"),
        #[cfg(unix)]
        d.join("sym.exr"),
    ] {
        let e = s.output(&bad).unwrap_err();
        assert!(
            matches!(e, WriteError::OutputIsInput { .. }),
            "{bad:?}: {e}"
        );
        assert!(e.is_usage());
    }
    s.output(&d.join("new/deep/o.csv")).unwrap();
    assert!(d.join("new/deep").is_dir());
    {
        // A session that commits nothing takes back the directories it made.
        let mut t = Session::new(false);
        t.output(&d.join("gone/too/x")).unwrap();
        assert!(d.join("gone/too").is_dir());
    }
    assert!(!d.join("gone").exists());
    let e = s.output(&d.join("new/./deep/../deep/o.csv")).unwrap_err();
    assert!(matches!(e, WriteError::SameOutput { .. }), "{e}");
    assert!(matches!(
        s.output(&d.join("sub/")),
        Err(WriteError::NoFileName(_))
    ));
    // An input declared after the output is caught too.
    let mut s = Session::new(false);
    s.output(&d.join("o2")).unwrap();
    assert!(s.input(&d.join("o2")).is_err());
    // Existing outputs: refused without overwrite; never a directory.
    assert!(matches!(
        Session::new(false).output(&input),
        Err(WriteError::Exists(_))
    ));
    assert!(matches!(
        Session::new(true).output(&d.join("sub")),
        Err(WriteError::NotRegular { .. })
    ));
}

#[test]
fn an_abort_removes_temporaries_and_stops_writes() {
    let dir = tempfile::tempdir().unwrap();
    let session = Session::new(false);
    let mut unit = session.unit();
    unit.write_bytes(&dir.path().join("a"), b"1").unwrap();
    let handle = session.abort_handle();
    assert_eq!(handle.abort(), 1);
    assert_eq!(leftovers(dir.path()), 0);
    assert!(matches!(
        unit.write_bytes(&dir.path().join("b"), b"2"),
        Err(WriteError::Aborted(_))
    ));
    assert!(matches!(unit.commit(), Err(WriteError::Aborted(_))));
    assert!(!dir.path().join("a").exists());
    assert_eq!(leftovers(dir.path()), 0);
}

/// The session as the library's batch sink: each frame's output and preview appear
/// together, staged until committed; a frame whose output exists fails alone (the batch
/// goes on), leaving no temporary.
#[test]
fn a_batch_commits_each_frame_through_the_session() {
    use nsrm_io::batch::{
        execute, plan_batch, ExecOptions, Existing, FrameOutcome, ModelCorrector, PlanOptions,
    };
    use nsrm_io::{FileFormat, ReadOptions, WriteOptions};
    let dir = tempfile::tempdir().unwrap();
    let (src, out, prev) = (dir.path(), dir.path().join("out"), dir.path().join("prev"));
    let mut inputs = Vec::new();
    for i in 0..3 {
        let p = src.join(format!("in{i}.tif"));
        let mut f = nsrm::Frame::new(4, 2, nsrm::Layout::Rgb);
        f.data.iter_mut().for_each(|v| *v = 0.1 + 0.1 * i as f32);
        let opts = WriteOptions {
            format: FileFormat::Tiff,
            ..WriteOptions::default()
        };
        Session::new(false)
            .unit()
            .write_with(&p, |w| nsrm_io::Decoded::from(f).write_to(&p, &opts, w))
            .map_err(|e: nsrm_io::IoError| e.to_string())
            .unwrap();
        inputs.push(p);
    }
    // The units above were dropped uncommitted: nothing of them is left.
    assert_eq!(leftovers(src), 0);
    assert!(!inputs[0].exists());
    for p in &inputs {
        let mut f = nsrm::Frame::new(4, 2, nsrm::Layout::Rgb);
        f.data.iter_mut().for_each(|v| *v = 0.25);
        let opts = WriteOptions {
            format: FileFormat::Tiff,
            ..WriteOptions::default()
        };
        let mut unit = Session::new(false).unit();
        unit.write_with(p, |w| nsrm_io::Decoded::from(f).write_to(p, &opts, w))
            .map_err(|e: nsrm_io::IoError| e.to_string())
            .unwrap();
        unit.commit().unwrap();
    }
    let plan = plan_batch(
        &inputs,
        &PlanOptions {
            out_dir: Some(&out),
            suffix: "_xyz",
            format: FileFormat::Tiff,
            preview_dir: Some(&prev),
            existing: Existing::Overwrite,
            shard: None,
            create_dirs: true,
        },
    )
    .unwrap();
    // Another process's file where the second frame's preview goes.
    std::fs::write(prev.join("in1_xyz.png"), b"theirs").unwrap();
    let session = Session::new(false);
    let training =
        nsrm::simulate_named("nikon-d5100", "D65", "cc24", &nsrm::Grid::default()).unwrap();
    let model = nsrm::fit(nsrm::Kind::Lrm, 1, &training).unwrap();
    let stop = AtomicBool::new(false);
    let opts = ExecOptions {
        sink: &session,
        read: ReadOptions::default(),
        write: WriteOptions {
            format: FileFormat::Tiff,
            ..WriteOptions::default()
        },
        highlights: nsrm::FrameHighlights::new(None, None, &[&model]),
        to_srgb: nsrm::to_linear_srgb(model.white_xyz(), nsrm::OutputSpace::Xyz),
        workers: 2,
        continue_on_error: true,
        stop: &stop,
    };
    let run = execute(
        &plan,
        &mut ModelCorrector::cpu(model.clone()),
        &opts,
        &|_| {},
    );
    let mut outcomes = run.outcomes;
    outcomes.sort_by_key(|(i, _)| *i);
    assert!(matches!(outcomes[0].1, FrameOutcome::Converted { .. }));
    assert!(
        matches!(outcomes[1].1, FrameOutcome::Failed(_)),
        "{outcomes:?}"
    );
    assert!(matches!(outcomes[2].1, FrameOutcome::Converted { .. }));
    // The failed frame's output did not appear without its preview, and the other
    // process's file is untouched; no temporary anywhere.
    assert!(out.join("in0_xyz.tif").exists() && prev.join("in0_xyz.png").exists());
    assert!(!out.join("in1_xyz.tif").exists());
    assert_eq!(std::fs::read(prev.join("in1_xyz.png")).unwrap(), b"theirs");
    assert_eq!(leftovers(&out) + leftovers(&prev), 0);
    assert_eq!(session.temporaries_held(), 0);
}
