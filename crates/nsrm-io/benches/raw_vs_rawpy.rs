//! Decoding a 24-Mpixel raw file: nsrm (rawler + its own demosaic) against rawpy (LibRaw) in the
//! same run. `cargo bench --bench raw_vs_rawpy [-- FILE.dng]`; without a file, a 6000 × 4000
//! 14-bit RGGB DNG is written with tests/tools/raw_judge.py (tifffile). Prints the median
//! seconds per decode of each and the ratios (rawpy time / nsrm time: > 1 means nsrm is faster).
//! Needs python3 with rawpy, tifffile and numpy (.ci/install.d/20-libraw.sh).

use nsrm_io::Demosaic;
use nsrm_io::{Decoded, ReadOptions};
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

const JUDGE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/tools/raw_judge.py");

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let arg = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let repeat = 5;
    let path = match arg {
        Some(p) => PathBuf::from(p),
        None => {
            let p = std::env::temp_dir().join("nsrm-bench-24mp.dng");
            if !p.exists() {
                let o = Command::new("python3")
                    .arg(JUDGE)
                    .args(["dng"])
                    .arg(&p)
                    .args([
                        "--width", "6000", "--height", "4000", "--black", "512", "--white",
                        "16383", "--bits", "14", "--smooth",
                    ])
                    .output()
                    .expect("python3");
                assert!(
                    o.status.success(),
                    "writing the DNG: {}",
                    String::from_utf8_lossy(&o.stderr)
                );
            }
            p
        }
    };
    println!("file: {}", path.display());
    let mut ours = Vec::new();
    for d in [Demosaic::Mhc, Demosaic::Bilinear, Demosaic::Half] {
        let opts = ReadOptions {
            demosaic: d,
            ..Default::default()
        };
        let f = Decoded::read(&path, &opts)
            .map(Decoded::into_frame)
            .expect("decoding");
        let px = f.pixels();
        drop(f);
        let ts: Vec<f64> = (0..repeat)
            .map(|_| {
                let t = Instant::now();
                let f = Decoded::read(&path, &opts)
                    .map(Decoded::into_frame)
                    .unwrap();
                let s = t.elapsed().as_secs_f64();
                drop(f);
                s
            })
            .collect();
        let m = median(ts);
        println!("nsrm {:<9} {:.3} s  ({} pixels out)", d.name(), m, px);
        ours.push((d, m));
    }
    let o = Command::new("python3")
        .arg(JUDGE)
        .arg("bench")
        .arg(&path)
        .arg(repeat.to_string())
        .output()
        .expect("python3");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value = serde_json::from_str(text.trim()).expect("rawpy timings");
    let (lin, half) = (v["linear"].as_f64().unwrap(), v["half"].as_f64().unwrap());
    println!("rawpy postprocess LINEAR    {lin:.3} s");
    println!("rawpy postprocess half_size {half:.3} s");
    for (d, m) in &ours {
        println!(
            "ratio rawpy LINEAR / nsrm {:<9} {:.2}×   rawpy half_size / nsrm {:<9} {:.2}×",
            d.name(),
            lin / m,
            d.name(),
            half / m
        );
    }
}
