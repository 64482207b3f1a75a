//! The frame type every apply path takes: the CPU reference, the fast CPU path and the GPU engine.

/// How a frame's channels are interleaved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Layout {
    /// Packed `R G B R G B …` f32.
    #[cfg_attr(feature = "clap", value(name = "rgb"))]
    Rgb,
    /// Packed `R G B A R G B A …` f32; alpha passes through unchanged.
    #[cfg_attr(feature = "clap", value(name = "rgba"))]
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

    /// Parses `rgb` / `rgba` (the unit test of the command line's `--layout` values holds them
    /// to it).
    pub fn parse(s: &str) -> Option<Layout> {
        match s.to_ascii_lowercase().as_str() {
            "rgb" => Some(Layout::Rgb),
            "rgba" => Some(Layout::Rgba),
            _ => None,
        }
    }

    /// `rgb` or `rgba`.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Rgb => "rgb",
            Layout::Rgba => "rgba",
        }
    }
}

/// A linear frame: `width × height` pixels of interleaved f32, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// RGB or RGBA.
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
}
