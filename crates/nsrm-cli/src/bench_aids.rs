//! What `nsrm bench` and `benches/kernels.rs` measure against: a synthetic camera frame and the
//! memcpy reference. Not part of the library; `benches/kernels.rs` includes this file.

use nsrm::{Frame, Layout};
use rayon::prelude::*;

/// A benchmark frame of camera RGB in a realistic range, from `seed`: channels 0..1 with a
/// camera-like balance, 2 % of pixels highlights up to ×8, alpha 1. Generated in parallel, the
/// same for any thread count.
pub(crate) fn synthetic_camera_rgb(
    width: usize,
    height: usize,
    layout: Layout,
    seed: u64,
) -> Frame {
    let ch = layout.channels();
    let mut frame = Frame::new(width, height, layout);
    frame
        .data
        .par_chunks_mut((1 << 16) * ch)
        .enumerate()
        .for_each(|(i, chunk)| {
            let mut state = seed ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            let mut next = || {
                state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
                let mut z = state;
                z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
                z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
                ((z ^ (z >> 31)) >> 40) as f32 / (1u32 << 24) as f32
            };
            for px in chunk.chunks_exact_mut(ch) {
                let gain = if next() < 0.02 {
                    1.0 + 7.0 * next()
                } else {
                    1.0
                };
                for (c, balance) in [0.55f32, 1.0, 0.75].into_iter().enumerate() {
                    px[c] = next() * balance * gain;
                }
                if ch == 4 {
                    px[3] = 1.0;
                }
            }
        });
    frame
}

/// The memcpy reference: `dst.copy_from_slice(src)` in chunks of `chunk` floats (the fast path's
/// 64 Ki pixels), on rayon's current pool when `parallel`, else on the calling thread, so a
/// kernel's throughput divided by this one's compares like with like.
pub(crate) fn memcpy_chunked(src: &[f32], dst: &mut [f32], chunk: usize, parallel: bool) {
    if parallel {
        src.par_chunks(chunk)
            .zip(dst.par_chunks_mut(chunk))
            .for_each(|(s, d)| d.copy_from_slice(s));
    } else {
        src.chunks(chunk)
            .zip(dst.chunks_mut(chunk))
            .for_each(|(s, d)| d.copy_from_slice(s));
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn synthetic_frame_is_seeded_and_in_range() {
        use super::*;
        let a = synthetic_camera_rgb(300, 300, Layout::Rgba, 7);
        assert_eq!(a.data, synthetic_camera_rgb(300, 300, Layout::Rgba, 7).data);
        assert_ne!(a.data, synthetic_camera_rgb(300, 300, Layout::Rgba, 8).data);
        for px in a.data.chunks_exact(4) {
            assert!(px[..3].iter().all(|v| (0.0..8.0).contains(v)), "{px:?}");
            assert_eq!(px[3], 1.0);
        }
        let mut dst = vec![0.0; a.data.len()];
        memcpy_chunked(&a.data, &mut dst, 4 << 16, true);
        assert_eq!(dst, a.data);
        let mut dst = vec![0.0; a.data.len()];
        memcpy_chunked(&a.data, &mut dst, 4 << 16, false);
        assert_eq!(dst, a.data);
    }
}
