//! The test kit shared by the integration tests (through `common`) and the library's unit tests
//! (`src/lib.rs` includes this file under `cfg(test)`, with `nsrm` naming the crate itself): one
//! seeded RNG, one generator of frames full of awkward pixels, the f64 reference on a frame, one
//! f32 error bound against it, the pixel policy's pixels and its check, one training fixture, the
//! one skip rule for a missing prerequisite ([`skip_or_fail`]: fails under `CI=true`) and the one
//! DCTL harness.
//! Public API only, so both sides compile it alike.

use nsrm::{simulate_named, Frame, Grid, Kind, Layout, Model, TrainingSet};
use std::io::Write as _;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::OnceLock;

/// The skip rule for a test whose prerequisite (an external tool, a driver, `../shared` data) is
/// absent: under `CI=true` it fails the test; otherwise it prints `SKIP: reason` and the caller
/// returns. (The integration tests' `common::skip` also counts the skipped tests.)
pub fn skip_or_fail(reason: &str) {
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!("{reason} (a prerequisite of this test, required under CI=true; docs/testing.md lists them)");
    }
    eprintln!("SKIP: {reason}");
}

/// SplitMix64: a fixed-seed generator (no extra dependency).
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    pub fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    /// Uniform in [a, b).
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.unit()
    }
    /// Uniform in 0..n.
    pub fn below(&mut self, n: u64) -> usize {
        (self.next_u64() % n) as usize
    }
}

/// One pixel of a given flavour (`flavour % 14`): ordinary, a zero channel, black, slightly
/// negative, HDR (×100), tiny (×1e-6), NaN, ±Inf, `s = R+G+B < 0`, −0, a single channel, mild
/// highlight.
pub fn awkward_pixel(rng: &mut Rng, flavour: usize) -> [f32; 3] {
    let mut p = [rng.unit(), rng.unit(), rng.unit()];
    let c = rng.below(3);
    match flavour % 14 {
        0 | 1 => {}                                              // ordinary 0..1
        2 => p[c] = 0.0,                                         // a zero channel
        3 => p = [0.0; 3],                                       // black
        4 => p[c] = -0.02 * rng.unit(),                          // noise around black
        5 => p.iter_mut().for_each(|v| *v *= 100.0),             // HDR highlight
        6 => p.iter_mut().for_each(|v| *v *= 1e-6),              // tiny
        7 => p[c] = f32::NAN,                                    // NaN
        8 => p[c] = f32::INFINITY,                               // +Inf
        9 => p[c] = f32::NEG_INFINITY,                           // −Inf
        10 => p = [-0.01 * rng.unit(), -0.01 * rng.unit(), 0.0], // s < 0
        11 => p[c] = -0.0,                                       // negative zero
        12 => p = [1e-3 + rng.unit(), 0.0, 0.0],                 // a single channel
        _ => p.iter_mut().for_each(|v| *v *= 4.0),               // mild highlight
    }
    p
}

/// A frame of [`awkward_pixel`]s of every flavour, from `seed`. Alpha (RGBA) is NaN, negative,
/// positive or a random bit pattern: every path must pass it through bit for bit.
pub fn awkward_frame(width: usize, height: usize, layout: Layout, seed: u64) -> Frame {
    let mut rng = Rng(seed);
    let ch = layout.channels();
    let mut data = Vec::with_capacity(width * height * ch);
    for _ in 0..width * height {
        let flavour = rng.below(14);
        data.extend_from_slice(&awkward_pixel(&mut rng, flavour));
        if ch == 4 {
            let a = match rng.below(4) {
                0 => f32::NAN,
                1 => -rng.unit(),
                2 => f32::from_bits(rng.next_u32()),
                _ => rng.unit(),
            };
            data.push(a);
        }
    }
    Frame::from_data(width, height, layout, data).unwrap()
}

/// The relative part of the f32 bound.
pub const F32_REL: f64 = 1e-5;

/// `T_k = |s|·Σ_j |m_kj·p_j|` in f64 (`p` the pixel's terms, `s` NSRM's scale or 1): the size of
/// the summands of output channel `k`. 0 where the model gives 0 (NSRM's `s ≤ 0`).
pub fn summands(model: &Model, rgb: [f64; 3]) -> [f64; 3] {
    let l = model.matrix().len() / 3;
    let mut p = vec![0.0; l];
    match model.features_of(rgb, &mut p) {
        None => [0.0; 3],
        Some(s) => [0, 1, 2].map(|k| {
            s.abs()
                * model.matrix()[k * l..(k + 1) * l]
                    .iter()
                    .zip(&p)
                    .map(|(m, v)| (m * v).abs())
                    .sum::<f64>()
        }),
    }
}

/// The one f32 error bound of every f32 path (fast CPU, GPU) against the f64 reference:
/// `|got − ref| ≤ rel · max(|ref|, T_k, 1e-30)`. Where nothing cancels `T_k = |ref|` and this is
/// a plain relative error; where the terms cancel to near 0, f32 summation cannot do better than
/// the rounding of the summands, and that is what `T_k` allows.
pub fn f32_bound(reference: f64, summands_k: f64, rel: f64) -> f64 {
    rel * reference.abs().max(summands_k).max(1e-30)
}

/// The training patches most tests fit on: the Nikon D5100 and rawtoaces-190 under D65.
pub fn training() -> &'static TrainingSet {
    static DATA: OnceLock<TrainingSet> = OnceLock::new();
    DATA.get_or_init(|| {
        simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap()
    })
}

/// The Nikon D5100 under `illuminant` on `reflectances`, on the default grid (unit tests of rooms
/// below `spectral` simulate through the kit).
pub fn simulated(illuminant: &str, reflectances: &str) -> TrainingSet {
    simulate_named("nikon-d5100", illuminant, reflectances, &Grid::default()).unwrap()
}

/// Every kind at every order (LRM once: it has only order 1), fitted on [`training`]: realistic
/// coefficients, including PRM 4's large ones of both signs.
pub fn fitted_models() -> Vec<Model> {
    let mut v = Vec::new();
    for kind in nsrm::Kind::ALL {
        for order in 1..=nsrm::MAX_ORDER {
            if kind == nsrm::Kind::Lrm && order > 1 {
                continue;
            }
            v.push(nsrm::fit(kind, order, training()).unwrap());
        }
    }
    v
}

/// Every kind at every order ([`fitted_models`]) and white-balanced NSRM (the pixel program's
/// gain step with gains other than 1) at every order: the models the pixel policy is checked on.
pub fn policy_models() -> Vec<Model> {
    let mut v = fitted_models();
    let opts = nsrm::FitOptions {
        normalise: nsrm::Normalise::WhiteBalanced,
        ..Default::default()
    };
    for order in 1..=nsrm::MAX_ORDER {
        let m = nsrm::fit_with(Kind::Nsrm, order, training(), &opts)
            .unwrap()
            .model;
        assert_ne!(m.input_gains(), [1.0; 3]);
        v.push(m);
    }
    v
}

/// The f64 reference on a frame, in place (alpha untouched): each pixel widened to f64, corrected
/// by [`Model::apply_f64`] and rounded once to f32: the oracle of the f32 paths.
pub fn apply_reference(model: &Model, frame: &mut Frame) {
    let ch = frame.layout.channels();
    for px in frame.data.chunks_exact_mut(ch) {
        let out = model.apply_f64([px[0], px[1], px[2]].map(f64::from));
        for k in 0..3 {
            px[k] = out[k] as f32;
        }
    }
}

/// The policy's pixels, by name. `huge` only where the model is exposure-invariant (PRM's cubes and
/// fourth powers of 1e30 overflow f32 as they would in any f32 evaluation).
pub fn policy_pixels(kind: Kind) -> Vec<(&'static str, [f32; 3])> {
    let mut v = vec![
        ("black", [0.0, 0.0, 0.0]),
        ("negative zero", [-0.0, -0.0, -0.0]),
        ("s < 0", [-0.01, -0.02, 0.0]),
        ("s < 0, one positive", [0.1, -0.2, 0.05]),
        ("s = 0, channels non-zero", [0.5, -0.5, 0.0]),
        ("negative channel, s > 0", [0.4, -0.05, 0.3]),
        ("two negative channels, s > 0", [-0.1, -0.05, 0.6]),
        ("NaN R", [f32::NAN, 0.2, 0.3]),
        ("NaN G", [0.2, f32::NAN, 0.3]),
        ("NaN B", [0.2, 0.3, f32::NAN]),
        ("+Inf", [f32::INFINITY, 0.2, 0.3]),
        ("-Inf", [0.2, f32::NEG_INFINITY, 0.3]),
        ("+Inf and -Inf", [f32::INFINITY, f32::NEG_INFINITY, 0.3]),
        ("tiny", [1e-30, 2e-30, 3e-30]),
        ("subnormal", [1e-40, 2e-40, 1e-40]),
        ("single channel", [0.7, 0.0, 0.0]),
        ("ordinary", [0.2, 0.3, 0.25]),
        ("highlight ×1e4", [2e3, 3e3, 2.5e3]),
    ];
    // PRM is the one kind that is not exposure-invariant (`f(kS) = k·f(S)` fails for it).
    if kind != Kind::Prm {
        v.push(("huge", [1e30, 2e30, 1.5e30]));
        v.push(("huge, negative channel", [1e30, -1e29, 1.5e30]));
    }
    v
}

pub fn policy_frame(pixels: &[(&str, [f32; 3])]) -> Frame {
    let data = pixels.iter().flat_map(|(_, p)| *p).collect();
    Frame::from_data(pixels.len(), 1, Layout::Rgb, data).unwrap()
}

/// Checks `out` (one path's result on `policy_pixels`) against the policy and the reference.
pub fn check_policy(model: &Model, path: &str, out: &Frame) {
    let pixels = policy_pixels(model.kind());
    let mut reference = policy_frame(&pixels);
    apply_reference(model, &mut reference);
    for (i, (name, x)) in pixels.iter().enumerate() {
        let got = &out.data[3 * i..3 * i + 3];
        let want = &reference.data[3 * i..3 * i + 3];
        let ctx = format!(
            "{} {} on {path}, pixel `{name}` {x:?}: got {got:?}, reference {want:?}",
            model.kind(),
            model.order()
        );
        let x64 = x.map(|v| v as f64);
        // NSRM's `s = R+G+B` of the pixel times the input gains (the program's gain step; 1, 1, 1
        // unless white-balanced).
        let g = model.input_gains();
        if model.kind() == Kind::Nsrm && x64[0] * g[0] + x64[1] * g[1] + x64[2] * g[2] <= 0.0 {
            assert!(got.iter().all(|v| *v == 0.0), "s ≤ 0 must give 0: {ctx}");
            continue;
        }
        if x.iter().any(|v| v.is_nan()) {
            assert!(got.iter().all(|v| v.is_nan()), "NaN must propagate: {ctx}");
            continue;
        }
        if model.kind() == Kind::Rprm && x.iter().all(|v| v.is_finite()) {
            assert!(
                got.iter().all(|v| v.is_finite()),
                "RPRM must stay finite: {ctx}"
            );
        }
        let t = summands(model, x64);
        let scale = want.iter().map(|v| (*v as f64).abs()).fold(0.0, f64::max);
        for k in 0..3 {
            let (g, w) = (got[k] as f64, want[k] as f64);
            if w.is_nan() {
                assert!(g.is_nan(), "expected NaN: {ctx}");
            } else if w.is_infinite() {
                assert!(!g.is_finite(), "expected non-finite: {ctx}");
            } else {
                let bound = 1e-5 * scale.max(t[k]) + 1e-30;
                assert!(
                    g.is_finite() && (g - w).abs() <= bound,
                    "channel {k}: error {:e} > {bound:e}: {ctx}",
                    (g - w).abs()
                );
            }
        }
    }
}

/// `base` with byte edits: each `(position, byte)` replaces, removes or inserts a byte at
/// `position % len` (chosen by `byte % 3`), from the characters a CSV or JSON parser cares about.
pub fn mutate(base: &str, edits: &[(usize, u8)]) -> String {
    let mut bytes = base.as_bytes().to_vec();
    for &(pos, b) in edits {
        if bytes.is_empty() {
            break;
        }
        let i = pos % bytes.len();
        match b % 3 {
            0 => bytes[i] = b" ,\n0123456789.-eNa#x"[(b as usize / 3) % 20],
            1 => {
                bytes.remove(i);
            }
            _ => bytes.insert(i, b",\n9-"[(b as usize / 3) % 4]),
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

// The one DCTL harness (the unit tests of `crates/nsrm-export/src/dctl.rs` and `dctl_tests.rs`, and the CLI
// test in `tests/all/gpu_export.rs`): Resolve is not available here, so a DCTL is compiled as C
// with a shim for its built-ins and run on test pixels.

/// DaVinci Resolve's DCTL built-ins as C: a DCTL compiles as C with this before it.
const SHIM: &str = r#"
#include <math.h>
#include <stdio.h>
#define __DEVICE__ static
#define DEVICE static
typedef struct { float x, y, z; } float3;
static float3 make_float3(float x, float y, float z) { float3 v; v.x = x; v.y = y; v.z = z; return v; }
#define _fabs fabsf
#define _sqrtf sqrtf
#define _cbrtf cbrtf
#define _copysignf copysignf
"#;

/// The C `main` that runs a DCTL's `transform` on `r g b` lines.
const MAIN: &str = r#"
int main(void) {
    float r, g, b;
    while (scanf("%f %f %f", &r, &g, &b) == 3) {
        float3 o = transform(1, 1, 0, 0, r, g, b);
        printf("%.9g %.9g %.9g\n", o.x, o.y, o.z);
    }
    return 0;
}
"#;

/// A C compiler for [`run_dctl`], or `None` after [`skip_or_fail`] (a failure under `CI=true`).
pub fn cc() -> Option<String> {
    for c in ["cc", "gcc", "clang"] {
        if Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
        {
            return Some(c.to_string());
        }
    }
    let msg = "no C compiler (cc, gcc or clang) to compile the DCTL with";
    skip_or_fail(msg);
    None
}

/// Runs `cmd` with `input` on its standard input, collecting its standard output and error.
pub fn piped(cmd: &mut Command, input: &str) -> std::process::Output {
    let mut child = cmd
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{cmd:?} does not start: {e}"));
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.as_bytes())
        .expect("writes");
    child.wait_with_output().expect("ends")
}

/// Runs a Python program (`python3 -c`) on `input`; its standard output (it must succeed).
pub fn python(code: &str, input: &str) -> String {
    let out = piped(
        Command::new("python3").args(["-W", "ignore", "-c", code]),
        input,
    );
    assert!(
        out.status.success(),
        "python failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Compiles `dctl` with the shim and runs it on `px` (also used by `pixel_policy`).
pub fn run_dctl(cc: &str, dir: &Path, name: &str, dctl: &str, px: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let src = dir.join(format!("{name}.c"));
    let exe = dir.join(name);
    std::fs::write(&src, format!("{SHIM}\n{dctl}\n{MAIN}")).unwrap();
    let out = Command::new(cc)
        .args([
            "-std=c99",
            "-O1",
            "-Wall",
            "-Werror",
            "-Wno-unused-parameter",
            "-Wno-unused-function",
        ])
        .arg(&src)
        .arg("-o")
        .arg(&exe)
        .arg("-lm")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{name}: the DCTL does not compile as C:\n{}\n{dctl}",
        String::from_utf8_lossy(&out.stderr)
    );
    let input: String = px
        .iter()
        .map(|p| format!("{:e} {:e} {:e}\n", p[0] as f32, p[1] as f32, p[2] as f32))
        .collect();
    let out = piped(&mut Command::new(&exe), &input);
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|t| match t {
                    "nan" | "-nan" => f64::NAN,
                    t => t.parse().unwrap(),
                })
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

/// Test pixels for a DCTL: training patches, 37× brighter and 1e-4× darker ones, black, `s < 0`
/// and grey, rounded to f32 (the C program reads f32).
pub fn dctl_pixels(data: &TrainingSet) -> Vec<[f64; 3]> {
    let mut px: Vec<[f64; 3]> = data.rgb.iter().take(60).cloned().collect();
    px.extend(data.rgb.iter().take(20).map(|c| c.map(|v| v * 37.0)));
    px.extend(data.rgb.iter().take(20).map(|c| c.map(|v| v * 1e-4)));
    px.extend([
        [0.0, 0.0, 0.0],
        [-0.01, 0.2, 0.3],
        [0.1, -0.2, 0.05],
        [0.1, -0.3, 0.05],
        [0.5, 0.5, 0.5],
    ]);
    // Round to f32 first: the C program reads f32.
    px.iter().map(|p| p.map(|v| v as f32 as f64)).collect()
}

/// A DCTL's output `got` on `px` against `model`: `|dctl − f64| ≤ 1e-5 · max(|ref|, T_k)` (`T_k` the size of the summands): the f32 bound of
/// the shaders (the kit's [`f32_bound`]).
pub fn check_dctl(model: &Model, px: &[[f64; 3]], got: &[[f64; 3]], what: &str) {
    assert_eq!(got.len(), px.len(), "{what}");
    for (x, g) in px.iter().zip(got) {
        let want = model.apply_f64(*x);
        let mag = summands(model, *x);
        for i in 0..3 {
            let tol = f32_bound(want[i], mag[i], 1e-5);
            assert!(
                (g[i] - want[i]).abs() <= tol,
                "{what}: pixel {x:?} channel {i}: DCTL {} vs f64 {} (tol {tol:e})",
                g[i],
                want[i]
            );
        }
    }
}

// The one RawTherapee harness (the DCP judges: `tests/all/profiles_rawtherapee.rs` develops the
// DCPs the binary writes and compares with `nsrm apply`; `crates/nsrm-export/src/dcp_tests.rs` finds the
// weight RawTherapee gave the two sides of a DCP the library writes and compares with nsrm's DNG
// evaluator): a synthetic chart DNG (written with tifffile: a Bayer mosaic of flat patches whose
// camera RGB is known, AsShotNeutral set, and the DCP's own ColorMatrix and
// CalibrationIlluminant tags, read from the DCP's IFD by the script) is developed by
// `rawtherapee-cli` with the DCP as input profile and Argyll's linear ProPhoto as output profile.
// Installed by `.ci/install.d/40-profiles.sh`.

/// Argyll's linear ProPhoto profile, RawTherapee's output profile here.
pub const LINEAR_PROPHOTO: &str = "/usr/share/color/argyll/ref/ProPhotoLin.icm";
/// Patch side in pixels and patches per row of the synthetic DNG (RawTherapee refuses very small
/// raw images: 160×80 is "Error loading file", 448×256 loads).
const RT_PATCH: usize = 64;
const RT_COLS: usize = 7;

/// Writes `dng` (Bayer RGGB, 16-bit, white level 65535, the ColorMatrix and CalibrationIlluminant
/// tags of the DCP `dcp`, copied as they are) and `tif` (the same camera RGB, one float pixel per
/// patch) from JSON on stdin; prints the camera RGB the mosaic holds.
const WRITE_DNG: &str = r#"
import json, struct, sys, numpy as np, tifffile
d = json.load(sys.stdin)
def dcp_tags(path):
    b = open(path, "rb").read()
    if b[:4] not in (b"IIRC", b"II*\x00"):
        sys.exit("not a little-endian DCP: %r" % b[:4])
    off, = struct.unpack_from("<I", b, 4)
    n, = struct.unpack_from("<H", b, off)
    tags = {}
    for i in range(n):
        e = off + 2 + 12 * i
        tag, typ, cnt = struct.unpack_from("<HHI", b, e)
        tags[tag] = (typ, cnt, b, e + 8)
    cm, ill = [], []
    for k in range(2):
        if 50721 + k not in tags:
            break
        typ, cnt, _, at = tags[50721 + k]
        if (typ, cnt) != (10, 9):
            sys.exit("ColorMatrix%d is not 9 SRATIONALs" % (k + 1))
        cm.append(list(struct.unpack_from("<18i", b, struct.unpack_from("<I", b, at)[0])))
        typ, cnt, _, at = tags[50778 + k]
        if (typ, cnt) != (3, 1):
            sys.exit("CalibrationIlluminant%d is not one SHORT" % (k + 1))
        ill.append(struct.unpack_from("<H", b, at)[0])
    if not cm:
        sys.exit("no ColorMatrix1")
    return cm, ill
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
for k, (cm, ill) in enumerate(zip(*dcp_tags(d["dcp"]))):
    tags += [(50721 + k, 10, 9, cm, True), (50778 + k, 3, 1, ill, True)]
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
/// mosaic's border), as JSON.
const READ_PATCHES: &str = r#"
import json, sys, numpy as np, tifffile
d = json.load(sys.stdin)
rt = tifffile.imread(d["rt"]).astype(np.float64)
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
print(json.dumps(vals))
"#;

/// Whether the RawTherapee harness can run: `Err(why)` names what is missing.
pub fn rawtherapee() -> Result<(), String> {
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

/// A chart developed by RawTherapee.
pub struct RtDeveloped {
    /// RawTherapee's patches in linear ProPhoto RGB (D50; the white's level is the camera
    /// white's G).
    pub prophoto: Vec<[f64; 3]>,
    /// The camera RGB in the mosaic (16-bit quantised).
    pub camera: Vec<[f64; 3]>,
    /// `camera` as a float TIFF, one pixel per patch (`dir/<tag>-patches.tif`).
    pub patches_tif: std::path::PathBuf,
}

/// Develops `patches` (camera RGB, 0..1, shot with the camera neutral `neutral`) with
/// RawTherapee and the DCP `dcp`, in `dir` (files named after `tag`).
pub fn rt_develop(
    dir: &Path,
    tag: &str,
    dcp: &Path,
    patches: &[[f64; 3]],
    neutral: [f64; 3],
) -> RtDeveloped {
    let dng = dir.join(format!("{tag}.dng"));
    let patches_tif = dir.join(format!("{tag}-patches.tif"));
    let req = serde_json::json!({
        "patches": patches,
        "neutral": neutral,
        "dcp": dcp,
        "size": RT_PATCH,
        "cols": RT_COLS,
        "dng": dng,
        "tif": patches_tif,
    });
    let camera: Vec<[f64; 3]> = serde_json::from_str(&python(WRITE_DNG, &req.to_string())).unwrap();
    let profile = dir.join(format!("{tag}.pp3"));
    std::fs::write(&profile, pp3(dcp)).unwrap();
    let rt_out = dir.join(format!("{tag}-rt.tif"));
    let o = Command::new("rawtherapee-cli")
        .args(["-q", "-Y", "-o"])
        .arg(&rt_out)
        .arg("-p")
        .arg(&profile)
        .args(["-t", "-b32", "-c"])
        .arg(&dng)
        .output()
        .expect("rawtherapee-cli runs");
    assert!(
        o.status.success() && rt_out.exists(),
        "rawtherapee-cli: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let read = serde_json::json!({
        "rt": rt_out,
        "size": RT_PATCH,
        "cols": RT_COLS,
        "n": patches.len(),
    });
    let prophoto = serde_json::from_str(&python(READ_PATCHES, &read.to_string())).unwrap();
    RtDeveloped {
        prophoto,
        camera,
        patches_tif,
    }
}

/// The CC24 under `light` as the Nikon D5100's camera RGB, the perfect white first (scaled so the
/// brightest channel of any patch is 0.8 of the white level); the camera's neutral for the light
/// (G = 1); and the perfect white's level (its G).
pub fn rt_chart(light: &str) -> (Vec<[f64; 3]>, [f64; 3], f64) {
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
