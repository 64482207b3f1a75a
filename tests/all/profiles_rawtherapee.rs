//! RawTherapee judges the DCP export: a synthetic chart DNG (written with tifffile: a Bayer
//! mosaic of flat patches whose camera RGB is known, AsShotNeutral and ColorMatrix set) is
//! developed by `rawtherapee-cli` with the exported DCP as input profile and Argyll's linear
//! ProPhoto as output profile; its patch values must match `nsrm apply` on the same camera RGB
//! (with `--white as-shot:R,G,B`) within the error `export` reports. Once for a single-illuminant
//! DCP (D65 frame), once for a two-illuminant one (StdA + D65) on a frame lit by a 4000 K
//! Planckian light, where the test also finds the weight RawTherapee gave the two sides (it
//! weights by its own white-balance temperature) and checks nsrm's DNG evaluator reproduces
//! RawTherapee at that weight. Installed by `.ci/install.d/40-profiles.sh`.

use crate::common::{nsrm_ok, python, skip, tempdir};
use nsrm::delta_e00_xyz;

use nsrm::export::{prophoto_to_xyz, Dcp};
use nsrm::OutputSpace;
use nsrm::D50_XY;
use nsrm::{simulate_named, Grid};
use nsrm::{FrameWhite, Profile};
use std::path::Path;
use std::process::Command;

const LINEAR_PROPHOTO: &str = "/usr/share/color/argyll/ref/ProPhotoLin.icm";
/// Patch side in pixels and patches per row of the synthetic DNG (RawTherapee refuses very small
/// raw images: 160×80 is "Error loading file", 448×256 loads).
const PATCH: usize = 64;
const COLS: usize = 7;

/// Writes `dng` (Bayer RGGB, 16-bit, white level 65535) and `tif` (the same camera RGB, one
/// float pixel per patch) from JSON on stdin.
const WRITE_DNG: &str = r#"
import json, sys, numpy as np, tifffile
d = json.load(sys.stdin)
p = np.array(d["patches"], dtype=np.float64)
size, cols = d["size"], d["cols"]
rows = (len(p) + cols - 1) // cols
img = np.zeros((rows * size, cols * size, 3))
for i, c in enumerate(p):
    r, q = divmod(i, cols)
    img[r*size:(r+1)*size, q*size:(q+1)*size] = c
raw = np.clip(np.round(img * 65535), 0, 65535).astype(np.uint16)
def rationals(m):
    out = []
    for v in np.asarray(m, dtype=np.float64).ravel():
        out += [int(round(v * 1e6)), 1000000]
    return out
tags = [
    (50706, 1, 4, (1, 4, 0, 0), True),
    (50707, 1, 4, (1, 1, 0, 0), True),
    (50708, 2, 0, "nsrm synthetic", True),
    (271, 2, 0, "nsrm", True),
    (272, 2, 0, "synthetic", True),
    (50717, 3, 1, 65535, True),
    (50714, 3, 1, 0, True),
    (50728, 5, 3, rationals(d["neutral"]), True),
    (33421, 3, 2, (2, 2), True),
    (33422, 1, 4, (0, 1, 1, 2), True),
]
for k, (cm, ill) in enumerate(zip(d["cm"], d["illuminant"])):
    tags += [(50721 + k, 10, 9, rationals(cm), True), (50778 + k, 3, 1, ill, True)]
mosaic = np.zeros(raw.shape[:2], dtype=np.uint16)
mosaic[0::2, 0::2] = raw[0::2, 0::2, 0]
mosaic[0::2, 1::2] = raw[0::2, 1::2, 1]
mosaic[1::2, 0::2] = raw[1::2, 0::2, 1]
mosaic[1::2, 1::2] = raw[1::2, 1::2, 2]
tifffile.imwrite(d["dng"], mosaic, photometric=32803, subfiletype=0, extratags=tags,
                 description=None, metadata=None, software=False)
# What the mosaic holds, exactly (16-bit quantised), for nsrm apply.
q = (np.round(np.clip(p, 0, 1) * 65535) / 65535).astype(np.float32)
tifffile.imwrite(d["tif"], q.reshape(1, -1, 3), photometric="rgb")
print(json.dumps(q.astype(np.float64).tolist()))
"#;

/// Prints the mean of the inner half of each patch of RawTherapee's TIFF (which crops the
/// mosaic's border) and nsrm's one-pixel-per-patch TIFF, as JSON.
const READ_PATCHES: &str = r#"
import json, sys, numpy as np, tifffile
d = json.load(sys.stdin)
rt = tifffile.imread(d["rt"]).astype(np.float64)
ns = tifffile.imread(d["nsrm"]).reshape(-1, 3).astype(np.float64)
size, cols, n = d["size"], d["cols"], d["n"]
rows = (n + cols - 1) // cols
oy = (rows * size - rt.shape[0]) // 2
ox = (cols * size - rt.shape[1]) // 2
q = size // 4
vals = []
for i in range(n):
    r, c = divmod(i, cols)
    y, x = r * size - oy, c * size - ox
    vals.append(rt[y+q:y+size-q, x+q:x+size-q, :3].reshape(-1, 3).mean(0).tolist())
print(json.dumps({"rt": vals, "nsrm": ns[:n].tolist(), "crop": [oy, ox]}))
"#;

fn prerequisites() -> Result<(), String> {
    let ok = |c: &mut Command| c.output().is_ok_and(|o| o.status.success());
    if !ok(Command::new("sh").args(["-c", "command -v rawtherapee-cli"])) {
        return Err("rawtherapee-cli is not installed (Debian rawtherapee)".into());
    }
    if !Path::new(LINEAR_PROPHOTO).exists() {
        return Err(format!("{LINEAR_PROPHOTO} is missing (Debian argyll)"));
    }
    if !ok(Command::new("python3").args(["-c", "import tifffile, numpy"])) {
        return Err("python3 with tifffile and numpy is not installed".into());
    }
    Ok(())
}

/// The dense-set maximum ΔE00 `export` printed ("… max X ΔE00 over N samples" is last).
fn reported_max(stdout: &str) -> f64 {
    stdout
        .rsplit("max ")
        .next()
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no error figure in {stdout}"))
}

/// A processing profile: the DCP as input profile (its hue/sat map, no look table, no tone
/// curve, no baseline exposure), camera white balance, no auto exposure, ProPhoto working space,
/// Argyll's linear ProPhoto as output profile (`file:` prefix, or RawTherapee silently falls back
/// to a gamma-encoded output).
fn pp3(dcp: &Path) -> String {
    format!(
        "[Exposure]\nAuto=false\nCompensation=0\nClip=0\nBrightness=0\nContrast=0\nSaturation=0\nHistogramMatching=false\nCurveMode=Standard\nCurve=0;\nCurve2=0;\n\n\
         [White Balance]\nEnabled=true\nSetting=Camera\n\n\
         [Color Management]\nInputProfile=file:{}\nToneCurve=false\nApplyLookTable=false\nApplyBaselineExposureOffset=false\nApplyHueSatMap=true\nDCPIlluminant=0\nWorkingProfile=ProPhoto\nOutputProfile=file:{LINEAR_PROPHOTO}\n",
        dcp.display()
    )
}

struct Developed {
    /// RawTherapee's patches as XYZ D50 and nsrm apply's, adapted to D50 (both with the white's
    /// Y as the camera white's G).
    rt: Vec<[f64; 3]>,
    nsrm: Vec<[f64; 3]>,
    /// The camera RGB in the mosaic (quantised).
    camera: Vec<[f64; 3]>,
}

/// Develops `patches` (camera RGB, 0..1) with RawTherapee and `dcp`, and applies `model` to
/// them with `nsrm apply --white as-shot:neutral`.
fn develop(
    dir: &Path,
    tag: &str,
    dcp: &str,
    model: &str,
    patches: &[[f64; 3]],
    neutral: [f64; 3],
) -> Developed {
    let parsed = Dcp::parse(&std::fs::read(dir.join(dcp)).unwrap()).unwrap();
    let req = serde_json::json!({
        "patches": patches,
        "neutral": neutral,
        "cm": parsed.sides.iter().map(|s| s.color_matrix).collect::<Vec<_>>(),
        "illuminant": parsed.sides.iter().map(|s| s.illuminant).collect::<Vec<_>>(),
        "size": PATCH,
        "cols": COLS,
        "dng": dir.join(format!("{tag}.dng")),
        "tif": dir.join(format!("{tag}-patches.tif")),
    });
    let camera: Vec<[f64; 3]> = serde_json::from_str(&python(WRITE_DNG, &req.to_string())).unwrap();
    let profile = dir.join(format!("{tag}.pp3"));
    std::fs::write(&profile, pp3(&dir.join(dcp))).unwrap();
    let rt_out = dir.join(format!("{tag}-rt.tif"));
    let o = Command::new("rawtherapee-cli")
        .args(["-q", "-Y", "-o"])
        .arg(&rt_out)
        .arg("-p")
        .arg(&profile)
        .args(["-t", "-b32", "-c"])
        .arg(dir.join(format!("{tag}.dng")))
        .output()
        .expect("rawtherapee-cli runs");
    assert!(
        o.status.success() && rt_out.exists(),
        "rawtherapee-cli: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let white = format!("as-shot:{},{},{}", neutral[0], neutral[1], neutral[2]);
    let out_dir = dir.join(format!("{tag}-nsrm"));
    nsrm_ok(
        dir,
        &[
            "apply",
            "--model",
            model,
            "--white",
            &white,
            "--output-space",
            "xyz",
            "--format",
            "tiff",
            "--device",
            "cpu",
            "-o",
            out_dir.to_str().unwrap(),
            &format!("{tag}-patches.tif"),
        ],
    );
    let read = serde_json::json!({
        "rt": rt_out,
        "nsrm": out_dir.join(format!("{tag}-patches_xyz.tif")),
        "size": PATCH,
        "cols": COLS,
        "n": patches.len(),
    });
    let v: serde_json::Value =
        serde_json::from_str(&python(READ_PATCHES, &read.to_string())).unwrap();
    let rows = |k: &str| -> Vec<[f64; 3]> { serde_json::from_value(v[k].clone()).unwrap() };
    let pp = prophoto_to_xyz();
    let d50 = crate::common::mat::xy_to_xyz(D50_XY);
    // nsrm's XYZ output is the frame white's XYZ adapted to D65 (unless that white is D65 to
    // within a tolerance), white Y = 1; the DCP's PCS is D50. Undo the one, adapt to the other.
    let white = Profile::load(&dir.join(model))
        .unwrap()
        .combine(FrameWhite::Neutral(neutral))
        .unwrap()
        .white_xyz;
    let written = OutputSpace::Xyz.from_xyz(white);
    let to_d50 = crate::common::mat::mul(
        &nsrm::bradford_between(white, d50),
        &crate::common::mat::invert(&written),
    );
    Developed {
        rt: rows("rt")
            .iter()
            .map(|c| crate::common::mat::apply(&pp, *c))
            .collect(),
        nsrm: rows("nsrm")
            .iter()
            .map(|c| crate::common::mat::apply(&to_d50, *c))
            .collect(),
        camera,
    }
}

/// ΔE00 per patch, the white at Y = `white_y` (the perfect white's level in the frame).
fn errors(a: &[[f64; 3]], b: &[[f64; 3]], white_y: f64) -> Vec<f64> {
    let w = crate::common::mat::xy_to_xyz(D50_XY).map(|v| v * white_y);
    a.iter()
        .zip(b)
        .map(|(x, y)| delta_e00_xyz(*x, *y, w))
        .collect()
}

fn stats(e: &[f64]) -> (f64, f64) {
    (
        e.iter().sum::<f64>() / e.len() as f64,
        e.iter().cloned().fold(0.0, f64::max),
    )
}

/// The chart under `light` as camera RGB, the perfect white first (scaled so the brightest
/// channel of any patch is 0.8 of the white level), and the camera's neutral for the light.
fn chart(light: &str) -> (Vec<[f64; 3]>, [f64; 3], f64) {
    let d = simulate_named("nikon-d5100", light, "cc24", &Grid::default()).unwrap();
    let n = d.white_rgb.unwrap();
    let mut v = vec![n];
    v.extend(d.rgb.iter().copied());
    let top = v.iter().flatten().cloned().fold(0.0, f64::max);
    let k = 0.8 / top;
    (
        v.iter().map(|c| c.map(|x| x * k)).collect(),
        n.map(|x| x / n[1]),
        n[1] * k,
    )
}

#[test]
fn rawtherapee_develops_the_dcp_as_nsrm_applies_the_model() {
    if let Err(why) = prerequisites() {
        return skip(&why);
    }
    let dir = tempdir("profiles-rt");
    crate::common::dual_nsrm_model(&dir);
    let export = |model: &str, out: &str| {
        let o = nsrm_ok(
            &dir,
            &["export", "--model", model, "--format", "dcp", "-o", out],
        );
        reported_max(&String::from_utf8_lossy(&o.stdout))
    };
    let single_max = export("d65.json", "d65.dcp");
    let dual_max = export("dual.json", "dual.dcp");

    // One illuminant, a D65 frame.
    let (patches, neutral, white_y) = chart("D65");
    let d = develop(&dir, "single", "d65.dcp", "d65.json", &patches, neutral);
    // RawTherapee keeps the exposure: the white comes out at the camera white's G level.
    let k = d.rt[0][1] / d.nsrm[0][1];
    assert!(
        (k - 1.0).abs() < 0.01,
        "RawTherapee scaled the white by {k}"
    );
    let e = errors(&d.rt, &d.nsrm, white_y);
    let (mean, max) = stats(&e);
    println!(
        "RawTherapee vs nsrm apply, single-illuminant DCP (D65 frame, {} patches): mean {mean:.4} / max {max:.4} ΔE00 (export reports a dense max of {single_max})",
        e.len()
    );
    assert!(max <= single_max, "{e:?}");

    // Two illuminants, a frame lit by a 4000 K Planckian light (between StdA and D65).
    let (patches, neutral, white_y) = chart("P4000");
    let d = develop(&dir, "dual", "dual.dcp", "dual.json", &patches, neutral);
    let e = errors(&d.rt, &d.nsrm, white_y);
    let (mean, max) = stats(&e);
    println!(
        "RawTherapee vs nsrm apply, two-illuminant DCP (4000 K frame, {} patches): mean {mean:.4} / max {max:.4} ΔE00 (export reports a dense max of {dual_max})",
        e.len()
    );
    assert!(max <= dual_max, "{e:?}");

    // Which weight of side 1 (StdA) did RawTherapee use? nsrm's DNG evaluator at weight w
    // against RawTherapee's patches; Adobe's rule gives the weight `Dcp::eval` finds.
    let dcp = Dcp::parse(&std::fs::read(dir.join("dual.dcp")).unwrap()).unwrap();
    let at = |w: f64| -> Vec<[f64; 3]> {
        d.camera
            .iter()
            .map(|c| dcp.eval_weighted(*c, neutral, w))
            .collect()
    };
    let (_, adobe_w) = dcp.eval(d.camera[0], neutral).unwrap();
    let mut best = (f64::INFINITY, 0.0);
    for i in 0..=1000 {
        let w = i as f64 / 1000.0;
        let (m, _) = stats(&errors(&d.rt, &at(w), white_y));
        if m < best.0 {
            best = (m, w);
        }
    }
    let (_, max_best) = stats(&errors(&d.rt, &at(best.1), white_y));
    let (mean_adobe, max_adobe) = stats(&errors(&d.rt, &at(adobe_w), white_y));
    let (mean_0, _) = stats(&errors(&d.rt, &at(0.0), white_y));
    let (mean_1, _) = stats(&errors(&d.rt, &at(1.0), white_y));
    let t = dcp.temperatures();
    let temp = |w: f64| 1.0 / (w / t[0] + (1.0 - w) / t[1]);
    println!(
        "RawTherapee weighted StdA by {:.3} (as at {:.0} K); the DNG rule on the same neutral gives {adobe_w:.3} ({:.0} K). nsrm's DNG evaluator vs RawTherapee: at RawTherapee's weight mean {:.4} / max {max_best:.4}, at the DNG rule's weight mean {mean_adobe:.4} / max {max_adobe:.4} ΔE00 (at D65 alone mean {mean_0:.3}, StdA alone {mean_1:.3})",
        best.1,
        temp(best.1),
        temp(adobe_w),
        best.0
    );
    // nsrm's evaluator of the DNG pipeline reproduces RawTherapee at RawTherapee's weight, and
    // that weight is told apart from either side alone.
    assert!(max_best < 0.1, "evaluator vs RawTherapee: max {max_best}");
    assert!(
        best.0 < 0.5 * mean_0.min(mean_1),
        "{best:?} {mean_0} {mean_1}"
    );
}
