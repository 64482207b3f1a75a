//! Writes noisy float camera plates for batch-conversion benchmarks (BENCHMARKS.md, "Batch
//! conversion"): `plate.1001.exr`, `plate.1002.exr`, … holding [`Frame::synthetic_camera_rgb`]
//! (fixed seeds), one part, `R`, `G`, `B` float, written by nsrm's own EXR writer.
//!
//! ```text
//! cargo run --release --example plates -- DIR [COUNT=4] [WxH=6000x4000] [COMPRESSION=zip]
//! ```
//!
//! COMPRESSION is one of `none`, `rle`, `zips`, `zip`, `piz`. Keep DIR outside the repository: four
//! 24-Mpixel float plates take about 1.1 GB.

use anyhow::{bail, Context, Result};
use nsrm::colorimetry::spaces::OutputSpace;
use nsrm::io::{write_exr, ExrCompression, FileFormat, WriteOptions, DEFAULT_ZIP_LEVEL};
use nsrm::{Frame, Layout};
use std::path::PathBuf;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(dir) = args.first().map(PathBuf::from) else {
        bail!("usage: plates DIR [COUNT=4] [WxH=6000x4000] [COMPRESSION=zip]");
    };
    let count: u32 = args.get(1).map_or(Ok(4), |s| s.parse()).context("COUNT")?;
    let size = args.get(2).map_or("6000x4000", String::as_str);
    let (w, h) = size
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<usize>().ok()?, h.parse::<usize>().ok()?)))
        .context("WxH")?;
    let compression = args.get(3).map_or("zip", String::as_str);
    let Some(compression) = ExrCompression::parse(compression) else {
        bail!("unknown compression `{compression}`");
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    for i in 0..count {
        let frame = Frame::synthetic_camera_rgb(w, h, Layout::Rgb, 1001 + u64::from(i));
        let path = dir.join(format!("plate.{}.exr", 1001 + i));
        let opts = WriteOptions {
            format: FileFormat::Exr,
            half: false,
            compression,
            space: OutputSpace::Acescg,
            overwrite: true,
            zip_level: DEFAULT_ZIP_LEVEL,
        };
        write_exr(&frame, &path, &opts).with_context(|| format!("writing {}", path.display()))?;
        println!("{}", path.display());
    }
    Ok(())
}
