//! Writes noisy float camera plates for batch-conversion benchmarks (BENCHMARKS.md, "Batch
//! conversion"): `plate.1001.exr`, `plate.1002.exr`, … one part, `R`, `G`, `B` float, written by
//! nsrm's own EXR writer. Each holds a smooth scene (mid grey ± 40 %, camera-like channel
//! balance) with 2 % Gaussian sensor noise (fixed seeds), which ZIP compresses to ~94 %, as
//! measured on real raw-converter output; uniform random data would not compress at all.
//!
//! ```text
//! cargo run --release --example plates -- DIR [COUNT=4] [WxH=6000x4000] [COMPRESSION=zip]
//! ```
//!
//! COMPRESSION is one of `none`, `rle`, `zips`, `zip`, `piz`. Keep DIR outside the repository: four
//! 24-Mpixel float plates take about 1.1 GB.

use anyhow::{bail, Context, Result};
use nsrm::OutputSpace;
use nsrm::{Frame, Layout};
use nsrm_io::{Decoded, ExrCompression, FileFormat, WriteOptions};
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
    let compression = match compression {
        "none" => ExrCompression::None,
        "rle" => ExrCompression::Rle,
        "zips" => ExrCompression::Zips,
        "zip" => ExrCompression::Zip,
        "piz" => ExrCompression::Piz,
        other => bail!("unknown compression `{other}`"),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    for i in 0..count {
        let frame = plate(w, h, 1001 + u64::from(i));
        let path = dir.join(format!("plate.{}.exr", 1001 + i));
        let opts = WriteOptions {
            format: FileFormat::Exr,
            half: false,
            compression,
            space: OutputSpace::Acescg,
            ..Default::default()
        };
        // The library encodes into any `Write + Seek`; where the bytes land is the caller's
        // (the `nsrm` command stages them in temporaries and commits them together).
        let mut file = std::io::BufWriter::new(
            std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?,
        );
        Decoded::from(frame)
            .write_to(&path, &opts, &mut file)
            .with_context(|| format!("writing {}", path.display()))?;
        std::io::Write::flush(&mut file)?;
        println!("{}", path.display());
    }
    Ok(())
}

/// A smooth scene with 2 % Gaussian noise; deterministic for a seed.
fn plate(w: usize, h: usize, seed: u64) -> Frame {
    use rayon::prelude::*;
    let mut frame = Frame::new(w, h, Layout::Rgb);
    frame
        .data
        .par_chunks_mut(3 * w)
        .enumerate()
        .for_each(|(y, row)| {
            let mut state = seed ^ (y as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            let mut uniform = || {
                state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
                let mut z = state;
                z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
                z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
                ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
            };
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                let base = 0.18 * (0.6 + 0.4 * (x as f64 / 300.0).sin() * (y as f64 / 200.0).cos());
                for (c, balance) in [0.55, 1.0, 0.75].into_iter().enumerate() {
                    // Box-Muller.
                    let (u1, u2) = (uniform().max(1e-300), uniform());
                    let n = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                    px[c] = (base * balance * (1.0 + 0.02 * n)) as f32;
                }
            }
        });
    frame
}
