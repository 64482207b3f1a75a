//! The executor's unit tests: events, a stop, failures (beside the code).

use super::*;
use crate::batch::{plan_batch, Existing, PlanOptions};
use nsrm::{Frame, Kind, Layout, OutputSpace};
use std::path::PathBuf;

/// `n` small float TIFF inputs in `dir` (the third one, with `broken`, not a TIFF at all).
fn inputs(dir: &Path, n: usize, broken: Option<usize>) -> Vec<PathBuf> {
    (0..n)
        .map(|i| {
            let p = dir.join(format!("in{i}.tif"));
            if broken == Some(i) {
                std::fs::write(&p, b"not a frame").unwrap();
                return p;
            }
            let mut f = Frame::new(8, 4, Layout::Rgb);
            for (k, v) in f.data.iter_mut().enumerate() {
                *v = 0.05 + (k % 7) as f32 * 0.1;
            }
            let mut w = std::io::BufWriter::new(std::fs::File::create_new(&p).unwrap());
            crate::tif::write(&f, None, &p, &mut w).unwrap();
            p
        })
        .collect()
}

fn model() -> Model {
    nsrm::fit(Kind::Lrm, 1, crate::kit::training()).unwrap()
}

/// The plan of `inputs` into `out`, and a sink writing files directly.
fn planned(inputs: &[PathBuf], out: &Path) -> (BatchPlan, Files) {
    let plan = plan_batch(
        inputs,
        &PlanOptions {
            out_dir: Some(out),
            suffix: "_xyz",
            format: crate::FileFormat::Tiff,
            preview_dir: None,
            existing: Existing::Refuse,
            shard: None,
            create_dirs: true,
        },
    )
    .unwrap();
    (plan, Files::default())
}

fn options<'a>(
    sink: &'a Files,
    model: &Model,
    stop: &'a AtomicBool,
    go_on: bool,
) -> ExecOptions<'a> {
    ExecOptions {
        sink,
        read: ReadOptions::default(),
        write: WriteOptions {
            format: crate::FileFormat::Tiff,
            ..WriteOptions::default()
        },
        highlights: FrameHighlights::new(None, None, &[model]),
        to_srgb: nsrm::to_linear_srgb(model.white_xyz(), OutputSpace::Xyz),
        workers: 1,
        continue_on_error: go_on,
        stop,
    }
}

/// The names of the files in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_stop_after_the_first_frame_leaves_the_rest_not_done_and_nothing_half_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let inputs = inputs(dir.path(), 4, None);
    let (plan, session) = planned(&inputs, &out);
    let m = model();
    let stop = AtomicBool::new(false);
    let opts = options(&session, &m, &stop, false);
    let seen = Mutex::new(Vec::new());
    let on_event = |e: Event<'_>| {
        if let Event::Done { index, pixels, .. } = e {
            assert_eq!(pixels, 32);
            // The caller's signal handler, in effect: stop after the first frame written.
            stop.store(true, Ordering::SeqCst);
            lock(&seen).push(format!("done {index}"));
        } else if let Event::Started { index, .. } = e {
            lock(&seen).push(format!("started {index}"));
        }
    };
    let mut corrector = ModelCorrector::cpu(m.clone());
    assert!(corrector.describe().starts_with("CPU ("));
    let run = execute(&plan, &mut corrector, &opts, &on_event);
    let seen = seen.into_inner().unwrap();
    assert_eq!(
        seen.first().map(String::as_str),
        Some("started 0"),
        "{seen:?}"
    );
    assert_eq!(
        seen.iter().filter(|s| s.starts_with("done")).count(),
        1,
        "{seen:?}"
    );
    assert_eq!(run.outcomes.len(), 1, "{:?}", run.outcomes);
    assert!(matches!(
        run.outcomes[0],
        (0, FrameOutcome::Converted { pixels: 32 })
    ));
    assert_eq!((run.timing.frames, run.timing.pixels), (1, 32));
    // The first output committed, and nothing else there: no other output, no temporary.
    assert_eq!(names(&out), ["in0_xyz.tif"]);
}

#[test]
fn a_stop_before_the_run_starts_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let inputs = inputs(dir.path(), 2, None);
    let (plan, session) = planned(&inputs, &out);
    let m = model();
    let stop = AtomicBool::new(true);
    let opts = options(&session, &m, &stop, false);
    let events = AtomicUsize::new(0);
    let on_event = |_: Event<'_>| {
        events.fetch_add(1, Ordering::SeqCst);
    };
    let run = execute(&plan, &mut ModelCorrector::cpu(m.clone()), &opts, &on_event);
    assert!(run.outcomes.is_empty());
    assert_eq!(events.load(Ordering::SeqCst), 0);
    assert!(names(&out).is_empty());
}

/// A corrector that fails on the frames of one input.
struct FailsOn(usize, ModelCorrector);

impl Correct for FailsOn {
    fn describe(&self) -> String {
        "test".into()
    }

    fn prepare(&mut self, frame: &Decoded) -> Result<Option<String>, CorrectError> {
        let name = frame.path.file_name().unwrap().to_string_lossy();
        Ok(Some(format!("preparing {name}")))
    }

    fn correct(&mut self, d: &mut Decoded, h: &FrameHighlights) -> Result<(), CorrectError> {
        if d.path.ends_with(format!("in{}.tif", self.0)) {
            return Err(CorrectError::Other("no luck".into()));
        }
        self.1.correct(d, h)
    }
}

#[test]
fn failures_are_told_and_returned_and_the_rest_go_on_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let inputs = inputs(dir.path(), 4, Some(2));
    let (plan, session) = planned(&inputs, &out);
    let m = model();
    let stop = AtomicBool::new(false);
    let opts = options(&session, &m, &stop, true);
    let failed = Mutex::new(Vec::new());
    let notes = AtomicUsize::new(0);
    let on_event = |e: Event<'_>| match e {
        Event::Failed { index, error, .. } => lock(&failed).push((index, error.to_string())),
        Event::Note { .. } => {
            notes.fetch_add(1, Ordering::SeqCst);
        }
        _ => {}
    };
    let mut corrector = FailsOn(1, ModelCorrector::cpu(m.clone()));
    let run = execute(&plan, &mut corrector, &opts, &on_event);
    let mut failed = failed.into_inner().unwrap();
    failed.sort();
    assert_eq!(failed.len(), 2, "{failed:?}");
    assert_eq!(failed[0].0, 1);
    assert!(
        failed[0].1.ends_with("in1.tif: correcting: no luck"),
        "{failed:?}"
    );
    assert_eq!(failed[1].0, 2);
    assert!(failed[1].1.contains("in2.tif"), "{failed:?}");
    // Every decoded frame was prepared (the broken one never decoded).
    assert_eq!(notes.load(Ordering::SeqCst), 3);
    let mut got: Vec<(usize, bool)> = run
        .outcomes
        .iter()
        .map(|(i, o)| (*i, matches!(o, FrameOutcome::Converted { .. })))
        .collect();
    got.sort();
    assert_eq!(got, [(0, true), (1, false), (2, false), (3, true)]);
    assert!(matches!(
        run.outcomes.iter().find(|(i, _)| *i == 2),
        Some((_, FrameOutcome::Failed(FrameError::Read(_))))
    ));
    assert_eq!(names(&out), ["in0_xyz.tif", "in3_xyz.tif"]);
}
