//! The unit tests of `apply.rs` (moved beside it to keep the file short).

use super::*;

fn plan(actions: Vec<(Action, bool)>) -> BatchPlan {
    BatchPlan {
        jobs: actions
            .into_iter()
            .enumerate()
            .map(|(i, (action, preview))| batch::Job {
                input: PathBuf::from(format!("in{i}.exr")),
                output: PathBuf::from(format!("out/in{i}.exr")),
                preview: preview.then(|| PathBuf::from(format!("prev/in{i}.png"))),
                action,
            })
            .collect(),
        total_inputs: 2,
        shard: None,
        dirs: Vec::new(),
    }
}

#[test]
fn dry_run_and_planned_outcomes_follow_the_plan() {
    let p = plan(vec![
        (Action::Convert, true),
        (Action::Skip("exists".into()), false),
    ]);
    assert_eq!(
        dry_run_lines(&p),
        [
            "in0.exr -> out/in0.exr (+ prev/in0.png)",
            "in1.exr -> out/in1.exr  # skip: exists"
        ]
    );
    let o = planned_outcomes(&p);
    assert!(o[0].is_none());
    assert!(matches!(&o[1], Some(Outcome::Skipped(w)) if w == "exists"));
}

#[test]
fn tally_counts_and_words_the_summary() {
    let outcomes = vec![
        Some(Outcome::Converted),
        Some(Outcome::Converted),
        Some(Outcome::Failed("x".into())),
        Some(Outcome::Aborted),
        None,
    ];
    let t = Tally::of(&outcomes);
    assert_eq!(
        t,
        Tally {
            converted: 2,
            skipped: 0,
            failed: 1,
            aborted: 1,
            not_attempted: 1
        }
    );
    let line = t.summary(Some("SIGINT"), "all 5", "cpu", "acescg exr half");
    assert_eq!(
            line,
            "nsrm apply: interrupted by SIGINT: 2 converted, 0 skipped, 1 failed, 1 aborted while being written, 1 not attempted (all 5; cpu; output acescg exr half)"
        );
    assert!(t
        .stop_note(Some("SIGINT"), 3)
        .unwrap()
        .contains("3 temporary file(s)"));
    assert!(t
        .stop_note(None, 0)
        .unwrap()
        .contains("--continue-on-error"));
    let clean = Tally::of(&[Some(Outcome::Converted)]);
    assert_eq!(clean.stop_note(None, 0), None);
    assert!(!clean.summary(None, "s", "c", "o").contains("not attempted"));
}

#[test]
fn a_camera_mismatch_is_warned_about_once() {
    let mut warned = std::collections::HashSet::new();
    let p = Path::new("a.nef");
    assert_eq!(
        camera_warning("Nikon D850", "NIKON D850", p, &mut warned),
        None
    );
    let w = camera_warning("Nikon D850", "Canon EOS R5", p, &mut warned).unwrap();
    assert!(
        w.contains("a.nef comes from a Canon EOS R5") && w.contains("Nikon D850"),
        "{w}"
    );
    assert_eq!(
        camera_warning("Nikon D850", "Canon EOS R5", p, &mut warned),
        None
    );
}

#[test]
fn workers_are_bounded_by_the_frames() {
    assert_eq!(workers(Some(8), 3), 3);
    assert_eq!(workers(Some(0), 3), 1);
    assert_eq!(workers(Some(2), 0), 1);
    assert!(workers(None, 1000) >= 1);
}
