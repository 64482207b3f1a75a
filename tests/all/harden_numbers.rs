//! Family 8 (numbers in flags cannot overflow) and the flag part of family 4 (values that would
//! overflow f32 or memory are refused with the limit in the message): usage errors, exit 2,
//! never a panic (debug builds check overflow, so a panic here would show).

use crate::common;
use common::*;

fn usage_error(args: &[&str], want: &str) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    exr(&d.join("a.exr"), 2, 2);
    let o = nsrm_in(d, args);
    no_crash(&o, &format!("{args:?}"));
    assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
}

#[test]
fn patch_specs_use_checked_arithmetic() {
    let fit = |spec: &'static str| {
        vec![
            "fit",
            "--reflectances",
            "cc24",
            "--patches",
            spec,
            "-o",
            "x.json",
        ]
    };
    usage_error(
        &fit("A1:B4294967295"),
        "the rectangle holds 8589934590 patches, more than the limit of 1048576",
    );
    usage_error(&fit("AAAAAAAA1:B2"), "too many to count");
    usage_error(&fit("A1:B99999999999"), "not a chart label");
    usage_error(&fit("A0:ZZZZZZ4294967295"), "patches");
}

#[test]
fn grid_shard_and_sizes_are_bounded() {
    usage_error(
        &["fit", "--grid", "0:1e300:1e-300", "-o", "x.json"],
        "more than 100000 samples",
    );
    usage_error(
        &["fit", "--grid", "400:700:0", "-o", "x.json"],
        "STEP must be positive",
    );
    let apply = |shard: &'static str| vec!["apply", "--model", "m.json", "--shard", shard, "a.exr"];
    usage_error(&apply("18446744073709551616/2"), "--shard");
    usage_error(&apply("2/18446744073709551616"), "--shard");
    usage_error(&apply("0/0"), "--shard");
    usage_error(
        &["bench", "--size", "100000x100000"],
        "limit of 268435456 pixels",
    );
    usage_error(
        &[
            "bench",
            "--size",
            "18446744073709551615x18446744073709551615",
        ],
        "limit",
    );
    usage_error(
        &["apply", "--model", "m.json", "--max-pixels", "0", "a.exr"],
        "--max-pixels",
    );
    let extract = |n: &'static str| {
        vec![
            "chart",
            "extract",
            "a.exr",
            "--chart",
            "cc24",
            "--max-pixels",
            n,
            "-o",
            "p.csv",
        ]
    };
    usage_error(&extract("0"), "--max-pixels");
    // A frame over the limit is refused before it is read, with the flag that lifts the limit.
    let dir = tempfile::tempdir().unwrap();
    exr(&dir.path().join("a.exr"), 2, 2);
    let o = nsrm_in(dir.path(), &extract("3"));
    no_crash(&o, "chart extract --max-pixels 3");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("more than the limit of 3 pixels"), "{err}");
    assert!(
        err.contains("hint: raise the limit with --max-pixels N"),
        "{err}"
    );
    assert!(!dir.path().join("p.csv").exists());
}

#[test]
fn render_chart_flags_are_bounded() {
    let rc = |flag: &'static str, v: &'static str| {
        vec![
            "render-chart",
            "--reflectances",
            "cc24",
            flag,
            v,
            "-o",
            "c.exr",
        ]
    };
    usage_error(
        &rc("--patch-size", "18446744073709551615"),
        "the limit is 16384 pixels",
    );
    usage_error(
        &rc("--gap", "18446744073709551615"),
        "the limit is 16384 pixels",
    );
    usage_error(&rc("--exposure", "1e39"), "1e30");
    usage_error(&rc("--exposure", "1e-300"), "1e-30");
    usage_error(&rc("--exposure", "inf"), "--exposure");
    usage_error(&rc("--noise", "1e300"), "1e30");
    usage_error(
        &[
            "render-chart",
            "--reflectances",
            "cc24",
            "--noise=-1",
            "-o",
            "c.exr",
        ],
        "--noise: noise -1 is out of range",
    );
    // The largest accepted values still give finite pixels.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = nsrm_in(
        d,
        &[
            "render-chart",
            "--reflectances",
            "cc24",
            "--patch-size",
            "1",
            "--exposure",
            "1e30",
            "--noise",
            "1e30",
            "-o",
            "c.exr",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let f = crate::common::read_frame(&d.join("c.exr"), &Default::default()).unwrap();
    assert!(f.data.iter().all(|v| v.is_finite()), "non-finite pixels");
    // Sizes that fit each flag but not together.
    usage_error(
        &[
            "render-chart",
            "--reflectances",
            "cc24",
            "--patch-size",
            "16384",
            "--gap",
            "16384",
            "-o",
            "c.exr",
        ],
        "too big",
    );
}
