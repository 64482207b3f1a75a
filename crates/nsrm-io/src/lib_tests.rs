//! Unit tests of the frame types and options (beside the code).

use super::*;

#[test]
fn frame_pool_reuses_and_stays_bounded() {
    let pool = FramePool::new(2);
    assert!(pool.take(10).is_none());
    pool.give(vec![1.0; 10]);
    pool.give(vec![2.0; 20]);
    pool.give(vec![3.0; 30]);
    assert_eq!(pool.idle(), 2, "at most `max` idle buffers");
    let v = pool.take(15).expect("the 20-sample buffer fits");
    assert_eq!(v.len(), 15);
    assert_eq!(pool.idle(), 1);
    // Nothing fits: one idle buffer is released instead.
    assert!(pool.take(100).is_none());
    assert_eq!(pool.idle(), 0);
    pool.give(Vec::new());
    assert_eq!(pool.idle(), 0, "empty buffers are not kept");
}

#[test]
fn format_names() {
    assert_eq!(FileFormat::parse("TIFF"), Some(FileFormat::Tiff));
    assert_eq!(
        FileFormat::from_extension(Path::new("a/b.EXR")),
        Some(FileFormat::Exr)
    );
    assert_eq!(FileFormat::from_extension(Path::new("a/b.png")), None);
}
