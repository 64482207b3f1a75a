//! The frame type every apply path takes: the CPU reference, the fast CPU path and the GPU engine.

use rayon::prelude::*;

/// How a frame's channels are interleaved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Layout {
    /// Packed `R G B R G B …` f32.
    Rgb,
    /// Packed `R G B A R G B A …` f32; alpha passes through unchanged.
    Rgba,
}

impl Layout {
    /// Floats per pixel: 3 or 4.
    pub fn channels(self) -> usize {
        match self {
            Layout::Rgb => 3,
            Layout::Rgba => 4,
        }
    }

    /// `rgb` or `rgba`.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Rgb => "rgb",
            Layout::Rgba => "rgba",
        }
    }

    /// Parses `rgb` / `rgba`.
    pub fn parse(s: &str) -> Option<Layout> {
        match s.to_ascii_lowercase().as_str() {
            "rgb" => Some(Layout::Rgb),
            "rgba" => Some(Layout::Rgba),
            _ => None,
        }
    }
}

/// A linear frame: `width × height` pixels of interleaved f32, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub width: usize,
    pub height: usize,
    pub layout: Layout,
    /// `width * height * layout.channels()` floats.
    pub data: Vec<f32>,
}

impl Frame {
    /// A frame of zeros.
    pub fn new(width: usize, height: usize, layout: Layout) -> Frame {
        Frame {
            width,
            height,
            layout,
            data: vec![0.0; width * height * layout.channels()],
        }
    }

    /// Wraps existing data; `None` if its length does not match.
    pub fn from_data(width: usize, height: usize, layout: Layout, data: Vec<f32>) -> Option<Frame> {
        (data.len() == width * height * layout.channels()).then_some(Frame {
            width,
            height,
            layout,
            data,
        })
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// A benchmark frame of camera RGB in a realistic range, from `seed`: channels 0..1 with a camera-like balance, 2 % of
    /// pixels highlights up to ×8, alpha 1. Generated in parallel, the same for any thread count.
    pub fn synthetic_camera_rgb(width: usize, height: usize, layout: Layout, seed: u64) -> Frame {
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
}
