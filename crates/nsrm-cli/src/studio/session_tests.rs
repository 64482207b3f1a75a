//! The unit tests of `session.rs` (moved beside it to keep the file short).

use super::*;

#[test]
fn quoting() {
    assert_eq!(quote("a.exr"), "a.exr");
    assert_eq!(quote("a b.exr"), "'a b.exr'");
    assert_eq!(quote("it's"), "'it'\\''s'");
    assert_eq!(quote(""), "''");
    assert_eq!(
        corners_text([[1.5, 2.0], [3.0, 4.0], [5.0, 6.0], [7.0, 8.25]]),
        "1.5,2 3,4 5,6 7,8.25"
    );
}

#[test]
fn page_messages_name_no_flags() {
    assert_eq!(
        unflag("--objective `x`: use --white-patch D4 or --ridge auto"),
        "objective `x`: use white patch D4 or ridge auto"
    );
    assert_eq!(unflag("a -- b --1 c"), "a -- b --1 c");
    let e = anyhow::Error::new(nsrm_io::IoError::OverLimit {
        path: "big.exr".into(),
        why: "10 pixels, more than the limit of 5".into(),
    });
    let m = explain_for_page(e);
    assert!(!m.contains("--"), "{m}");
    assert!(m.contains("Way out"), "{m}");
}

#[test]
fn box_filter() {
    let f = Frame::from_data(4, 2, Layout::Rgb, (0..24).map(|v| v as f32).collect()).unwrap();
    let s = downsample(&f, 2);
    assert_eq!((s.width, s.height), (2, 1));
    // Pixels 0, 1, 4, 5: R = (0 + 3 + 12 + 15) / 4.
    assert_eq!(s.data[0], 7.5);
}
