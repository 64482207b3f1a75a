//! Synthetic captures of a chart: the chart (camera RGB simulated from its spectra) placed by a
//! projective transform on a cluttered background, lit unevenly (vignetting and a linear light
//! gradient), optionally partly occluded, blurred, with seeded sensor noise and clipping. The
//! noise-free patch values and the pose are kept as ground truth ([`SceneTruth`]).
//!
//! Why one file (about 1,700 lines): a rendered scene is one seeded draw sequence (pose, light,
//! raster, the family's look, impostors), and `chart rate`'s figures depend on its order: splitting
//! it would make a change of draw order easy to miss. The unit tests are in `scene_tests.rs`.

use super::synthetic::Gaussian;
use super::{ChartError, ChartKind, Homography};
use nsrm::{simulate, Camera, Grid, Illuminant, Reflectances};
use nsrm::{Concern, Param};
use nsrm::{Frame, Layout};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` field of a scene truth file.
pub(crate) const FORMAT: &str = "nsrm-scene";

/// Camera RGB of a chart's patches and of its surroundings, perfect white `G = 1`.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartColours {
    /// The chart simulated.
    pub chart: ChartKind,
    /// Camera RGB per cell (index `r * columns + c`).
    pub rgb: Vec<[f64; 3]>,
    /// Simulated XYZ per cell (perfect white Y = 100 under the illuminant).
    pub xyz: Vec<[f64; 3]>,
    /// Camera RGB of the perfect white.
    pub white_rgb: [f64; 3],
    /// The camera's name or file.
    pub camera: String,
    /// The illuminant's name or file.
    pub illuminant: String,
    /// The reflectances' name or file.
    pub reflectances: String,
}

impl ChartColours {
    /// Simulates the chart: CC24 from the built-in BabelColor spectra (`reflectances` = `None`
    /// or `cc24`), SG from a spectra file whose columns are the labels `A1` … `N10`, the
    /// SpyderCHECKR 24 from 24 spectra in the classic's order (by default the classic's, as its
    /// colours are the classic's: no spectra of the SpyderCHECKR are published) or from a file
    /// whose columns are its labels.
    pub fn simulate(
        chart: ChartKind,
        camera: &str,
        illuminant: &str,
        reflectances: Option<&str>,
    ) -> Result<ChartColours, ChartError> {
        let err = |e: nsrm::SpectralError| ChartError::Invalid(e.to_string());
        let refl_name = match (chart, reflectances) {
            (_, Some(r)) => r.to_string(),
            // No spectra of the SpyderCHECKR are published: its colours are the classic's, so
            // the classic's spectra in its layout stand in for them ([`spyder24_cell`]).
            (ChartKind::Cc24 | ChartKind::Spyder24, None) => "cc24".to_string(),
            (ChartKind::Sg, None) => {
                return Err(ChartError::Param {
                    concern: Concern::Remedy(Param::Reflectances),
                    why: "an SG scene needs its spectra: a reflectance CSV with columns A1..N10 \
                          (e.g. ../shared/data/colorchecker_sg_140.csv)"
                        .into(),
                })
            }
        };
        let cam = Camera::from_name_or_path(camera).map_err(err)?;
        let ill = Illuminant::from_name_or_path(illuminant).map_err(err)?;
        let refl = Reflectances::from_name_or_path(&refl_name).map_err(err)?;
        let grid = Grid::default();
        let data = simulate(&cam, &ill, &refl, &grid).map_err(err)?;
        let mut rgb = vec![None; chart.cells()];
        let mut xyz = vec![[0.0; 3]; chart.cells()];
        let by_index = chart.cells() == 24 && data.len() == 24;
        for (j, label) in data.labels.iter().enumerate() {
            let i = match chart {
                ChartKind::Cc24 if by_index => Some(j),
                ChartKind::Spyder24 if by_index => Some(spyder24_cell(j)),
                _ => chart.index_of(label),
            };
            if let Some(i) = i {
                rgb[i] = Some(data.rgb[j]);
                xyz[i] = data.xyz[j];
            }
        }
        if rgb.iter().any(Option::is_none) {
            return Err(ChartError::Invalid(format!(
                "reflectances {refl_name}: their columns do not name every patch of a {} chart",
                chart.name()
            )));
        }
        let white = simulate(&cam, &ill, &Reflectances::perfect_white(), &grid).map_err(err)?;
        Ok(ChartColours {
            chart,
            rgb: rgb.into_iter().map(|v| v.expect("checked")).collect(),
            xyz,
            white_rgb: white.rgb[0],
            camera: cam.source_name().to_string(),
            illuminant: ill.source_name().to_string(),
            reflectances: refl.source_name().to_string(),
        })
    }
}

/// How a scene is rendered.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneOptions {
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// The patch-grid corners in the frame (as `--corners`); `None`: a seeded random pose.
    pub corners: Option<[[f64; 2]; 4]>,
    /// Seed of the pose, noise and clutter.
    pub seed: u64,
    /// Multiplies camera RGB (the perfect white, evenly lit, has `G = exposure`).
    pub exposure: f64,
    /// Values are clipped here.
    pub white_level: f64,
    /// Standard deviation of additive noise.
    pub noise: f64,
    /// Shot noise: variance added per unit of signal.
    pub shot_noise: f64,
    /// Gaussian blur σ in pixels (0: none).
    pub blur: f64,
    /// Light fall-off at the frame corners (0: none, 0.4: corners at 60 %).
    pub vignetting: f64,
    /// A linear light gradient across the frame (0.3: ±15 % around the middle).
    pub gradient: f64,
    /// Number of random shapes in the background.
    pub clutter: usize,
    /// An opaque object over a corner of the chart.
    pub occlusion: bool,
    /// Random pose: chart body area as a fraction of the frame, and the largest tilt.
    pub min_area: f64,
    /// Random pose: the largest chart body area as a fraction of the frame.
    pub max_area: f64,
    /// Random pose: the largest tilt (degrees).
    pub max_tilt_deg: f64,
    /// Smallest tilt of a random pose (degrees; the tilt is drawn from `min..max`).
    pub min_tilt_deg: f64,
    /// Random pose: `None` puts the camera 1.6 chart diagonals from the chart's centre;
    /// `Some(P)` brings it as close as needed (a wide-angle camera) for the patch scale to vary
    /// by `P` across the chart (1..=4; the measure of `nsrm_chart::detect`'s perspective limit), but
    /// no closer than a tenth of a diagonal in front of the chart's nearest corner: the pose's
    /// tilt must allow `P` (from 30° on, that camera shows at least 2.2 whatever the tilt's axis).
    pub perspective: Option<f64>,
    /// Reflectance of the chart body (neutral).
    pub body_reflectance: f64,
    /// A camera's display rendering on top: tone curve, saturation, 8-bit sRGB and JPEG, then
    /// decoded back with the plain sRGB transfer function (what nsrm reads from a camera JPEG).
    pub look: Option<CameraLook>,
    /// A ColorChecker Passport: its second page (creative enhancement: greys, skin tones,
    /// colours in another layout) open beside the classic page.
    pub second_page: bool,
    /// Textured ground (leaf litter): the background covered edge to edge by flat-ish leaves
    /// about this many of the chart's patch pitches across, each shaded along its own direction,
    /// with dark gaps between them (0: none; at most 10).
    pub texture: f64,
}

/// A camera's rendering of a scene into a JPEG.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraLook {
    /// Strength of the S-shaped contrast curve applied after the sRGB encoding (0: none;
    /// cameras: about 1 to 3).
    pub contrast: f64,
    /// Saturation gain in the display-encoded values (1: none; cameras: 1.1 to 1.5).
    pub saturation: f64,
    /// JPEG quality (1..=100); 0: 8-bit quantisation only.
    pub quality: u8,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            width: 1200,
            height: 800,
            corners: None,
            seed: 1,
            exposure: 1.0,
            white_level: 1.0,
            noise: 0.001,
            shot_noise: 0.0,
            blur: 0.0,
            vignetting: 0.0,
            gradient: 0.0,
            clutter: 20,
            occlusion: false,
            min_area: 0.1,
            max_area: 0.4,
            max_tilt_deg: 30.0,
            min_tilt_deg: 0.0,
            perspective: None,
            body_reflectance: 0.035,
            look: None,
            second_page: false,
            texture: 0.0,
        }
    }
}

impl SceneOptions {
    /// A seeded scene inside the detection envelope: any rotation, tilt up to 30°, the chart
    /// covering 5–40 % of the frame, exposure from just clipping the brightest patch down to
    /// 1/16 of that, vignetting up to 40 %, a light gradient up to 30 %, blur σ up to 1.2 px,
    /// noise (σ = 0.002 plus shot noise), 25 background shapes.
    pub fn envelope(colours: &ChartColours, width: usize, height: usize, seed: u64) -> Self {
        let mut g = Gaussian::new(seed ^ 0x05ee_d0f5_ce4e);
        let brightest = colours.rgb.iter().flatten().copied().fold(0.0, f64::max);
        let exposure = 1.0 / brightest * 2f64.powf(-4.0 * g.uniform());
        SceneOptions {
            width,
            height,
            corners: None,
            seed,
            exposure,
            white_level: 1.0,
            noise: 0.002,
            shot_noise: 2e-5,
            blur: 1.2 * g.uniform(),
            vignetting: 0.4 * g.uniform(),
            gradient: 0.3 * g.uniform(),
            clutter: 25,
            occlusion: false,
            min_area: 0.05,
            max_area: 0.4,
            max_tilt_deg: 30.0,
            min_tilt_deg: 0.0,
            perspective: None,
            body_reflectance: 0.035,
            look: None,
            second_page: false,
            texture: 0.0,
        }
    }

    fn check(&self) -> Result<(), ChartError> {
        let bad = |w: &str| Err(ChartError::Options(w.to_string()));
        if self.width < 16 || self.height < 16 || self.width.saturating_mul(self.height) > 1 << 27 {
            return bad("the frame must be 16×16 to 134 Mpixels");
        }
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let nonneg = |v: f64| v.is_finite() && v >= 0.0;
        // The bounds of a rendered chart: every pixel stays a finite 32-bit float.
        let (lo, hi) = super::synthetic::EXPOSURE_RANGE;
        let max_noise = super::synthetic::MAX_NOISE;
        let within = |v: f64| pos(v) && (lo..=hi).contains(&v);
        if !(within(self.exposure) && within(self.white_level)) {
            return Err(ChartError::Options(format!(
                "exposure {:e} and white level {:e} must be within {lo:e}..{hi:e} (so that the \
                 pixels stay finite, non-zero 32-bit floats)",
                self.exposure, self.white_level
            )));
        }
        if !(nonneg(self.noise)
            && nonneg(self.shot_noise)
            && self.noise <= max_noise
            && self.shot_noise <= max_noise
            && nonneg(self.blur)
            && self.blur <= 20.0)
        {
            return Err(ChartError::Options(format!(
                "noise {:e} and shot noise {:e} must be within 0..{max_noise:e} and blur {} \
                 within 0..20 px",
                self.noise, self.shot_noise, self.blur
            )));
        }
        if !(nonneg(self.vignetting)
            && self.vignetting < 1.0
            && nonneg(self.gradient)
            && self.gradient < 1.0)
        {
            return bad("vignetting and gradient must be in [0, 1)");
        }
        if !(self.min_area > 0.0 && self.min_area <= self.max_area && self.max_area <= 0.9) {
            return bad("chart area fractions must satisfy 0 < min ≤ max ≤ 0.9");
        }
        if !(nonneg(self.min_tilt_deg)
            && self.min_tilt_deg <= self.max_tilt_deg
            && self.max_tilt_deg <= 60.0)
        {
            return bad("the tilt must be 0..60° (and the smallest at most the largest)");
        }
        if self
            .perspective
            .is_some_and(|p| !(p.is_finite() && (1.0..=4.0).contains(&p)))
        {
            return bad("the perspective must be 1..4");
        }
        if !(nonneg(self.texture) && self.texture <= 10.0) {
            return bad("the texture (leaf size in patch pitches) must be 0..10");
        }
        if self.clutter > 10_000 {
            return bad("at most 10000 clutter shapes");
        }
        if let Some(l) = self.look {
            let ok = nonneg(l.contrast)
                && l.contrast <= 10.0
                && (0.0..=3.0).contains(&l.saturation)
                && l.quality <= 100;
            if !ok {
                return bad(
                    "the camera look needs contrast 0..10, saturation 0..3, quality 0..100",
                );
            }
        }
        Ok(())
    }
}

/// One patch of a scene, as it truly is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruePatch {
    /// The patch label.
    pub label: String,
    /// Noise-free camera RGB × exposure (the light normalised to 1 on average over the patches).
    pub rgb: [f64; 3],
    /// `rgb` × the light at the patch (before clipping): what an uncompensated reading sees.
    pub rgb_lit: [f64; 3],
    /// Simulated XYZ (perfect white Y = 100 under the illuminant).
    pub xyz: [f64; 3],
    /// Centre of the patch in the frame (pixels).
    pub centre: [f64; 2],
    /// The patch is partly hidden by the occluder.
    pub occluded: bool,
    /// Some channel of `rgb_lit` reaches the white level.
    pub clipped: bool,
}

/// Ground truth of a rendered scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneTruth {
    /// `nsrm-scene`.
    pub format: String,
    /// The file format's version.
    pub version: u32,
    /// The chart drawn.
    pub chart: ChartKind,
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// The seed rendered with.
    pub seed: u64,
    /// Chart coordinates → frame pixels (in the truth file; crate-private in the API).
    pub homography: Homography,
    /// The patch-grid corners in the frame (what `--corners` takes).
    pub corners: [[f64; 2]; 4],
    /// The chart body's corners in the frame.
    pub body_corners: [[f64; 2]; 4],
    /// Chart body area as a fraction of the frame.
    pub area_fraction: f64,
    /// In-plane rotation of the pose (degrees).
    pub rotation_deg: f64,
    /// Tilt of the pose (degrees).
    pub tilt_deg: f64,
    /// As [`SceneOptions::exposure`].
    pub exposure: f64,
    /// As [`SceneOptions::white_level`].
    pub white_level: f64,
    /// As [`SceneOptions::noise`].
    pub noise: f64,
    /// As [`SceneOptions::shot_noise`].
    pub shot_noise: f64,
    /// As [`SceneOptions::blur`].
    pub blur: f64,
    /// As [`SceneOptions::vignetting`].
    pub vignetting: f64,
    /// As [`SceneOptions::gradient`].
    pub gradient: f64,
    /// max/min of the light over the patch centres.
    pub light_nonuniformity: f64,
    /// The camera simulated.
    pub camera: String,
    /// The illuminant simulated.
    pub illuminant: String,
    /// The reflectances simulated.
    pub reflectances: String,
    /// Every patch as it truly is, in the chart's reading order.
    pub patches: Vec<TruePatch>,
    /// Set for a scene of a negative family (the name of the family): the chart drawn is not
    /// the one named by `chart`, and `patches` is empty — no reading of it is right.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub impostor: Option<String>,
}

/// The truth file written beside a scene frame: `NAME.scene.json` for `NAME.exr`.
pub fn truth_path(frame: &Path) -> PathBuf {
    frame.with_extension("scene.json")
}

fn quad_area(q: &[[f64; 2]; 4]) -> f64 {
    let mut a = 0.0;
    for k in 0..4 {
        let (p, n) = (q[k], q[(k + 1) % 4]);
        a += p[0] * n[1] - n[0] * p[1];
    }
    (a / 2.0).abs()
}

/// Camera distance of a random pose, in chart body diagonals (unless a perspective is asked for).
const CAMERA_DISTANCE: f64 = 1.6;

/// The camera distance (chart units) at which the pose `at(distance)` (chart → image) shows
/// perspective `target` ([`super::detect::perspective`], which falls as the camera moves
/// away), found by bisection between `closest` and 64 × `closest`; `closest` when even that
/// shows less.
fn camera_distance(
    kind: ChartKind,
    target: f64,
    closest: f64,
    at: impl Fn(f64) -> Result<Homography, ChartError>,
) -> Result<f64, ChartError> {
    let persp = |d: f64| at(d).map(|h| super::detect::perspective(kind, &h));
    let (mut near, mut far) = (closest, 64.0 * closest);
    if persp(near)? <= target {
        return Ok(near);
    }
    for _ in 0..60 {
        let mid = 0.5 * (near + far);
        if persp(mid)? > target {
            near = mid;
        } else {
            far = mid;
        }
    }
    Ok(far)
}

/// A random pose: (homography chart → frame, rotation°, tilt°).
fn random_pose(
    kind: ChartKind,
    opts: &SceneOptions,
    g: &mut Gaussian,
) -> Result<(Homography, f64, f64), ChartError> {
    let (w, h) = (opts.width as f64, opts.height as f64);
    let body = kind.body_corners();
    let (cc, rr) = (kind.columns() as f64 / 2.0, kind.rows() as f64 / 2.0);
    let theta = std::f64::consts::TAU * g.uniform();
    // (With no smallest tilt this is exactly the envelope's draw, so seeded scenes stay the same.)
    let tilt = opts.min_tilt_deg.to_radians()
        + (opts.max_tilt_deg - opts.min_tilt_deg).to_radians() * g.uniform();
    let phi = std::f64::consts::TAU * g.uniform();
    let area = opts.min_area + (opts.max_area - opts.min_area) * g.uniform();
    let diag = (2.0 * (cc + kind.margin())).hypot(2.0 * (rr + kind.margin()));
    // Rotation by `tilt` about the in-plane axis (cos φ, sin φ, 0), then by θ about the view axis.
    let (ax, ay) = (phi.cos(), phi.sin());
    let (ct, st) = (tilt.cos(), tilt.sin());
    let rot_tilt = [
        [ct + ax * ax * (1.0 - ct), ax * ay * (1.0 - ct), ay * st],
        [ax * ay * (1.0 - ct), ct + ay * ay * (1.0 - ct), -ax * st],
        [-ay * st, ax * st, ct],
    ];
    // Seen by a pinhole camera at `dist` from the chart's centre (chart units).
    let project = |p: [f64; 2], dist: f64| -> [f64; 2] {
        let v = [p[0] - cc, p[1] - rr, 0.0];
        let t: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| rot_tilt[i][j] * v[j]).sum())
            .collect();
        let (x, y) = (
            theta.cos() * t[0] - theta.sin() * t[1],
            theta.sin() * t[0] + theta.cos() * t[1],
        );
        let z = dist + t[2];
        [dist * x / z, dist * y / z]
    };
    let dist = match opts.perspective {
        None => CAMERA_DISTANCE * diag,
        // The closest camera: a tenth of a diagonal in front of the nearest body corner.
        Some(target) => camera_distance(kind, target, (0.5 * st + 0.1) * diag, |d| {
            Homography::from_points(&body, &body.map(|p| project(p, d)))
        })?,
    };
    let mut q = body.map(|p| project(p, dist));
    let s0 = (area * w * h / quad_area(&q)).sqrt();
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for p in &q {
        x0 = x0.min(p[0]);
        y0 = y0.min(p[1]);
        x1 = x1.max(p[0]);
        y1 = y1.max(p[1]);
    }
    let margin = 0.02 * w.min(h);
    let fit = ((w - 2.0 * margin) / (x1 - x0)).min((h - 2.0 * margin) / (y1 - y0));
    let s = s0.min(fit);
    let (bw, bh) = ((x1 - x0) * s, (y1 - y0) * s);
    let tx = margin + (w - 2.0 * margin - bw) * g.uniform() - x0 * s;
    let ty = margin + (h - 2.0 * margin - bh) * g.uniform() - y0 * s;
    for p in q.iter_mut() {
        *p = [p[0] * s + tx, p[1] * s + ty];
    }
    let hom = Homography::from_points(&body, &q)?;
    Ok((hom, theta.to_degrees(), tilt.to_degrees()))
}

enum Shape {
    Rect {
        c: [f64; 2],
        half: [f64; 2],
        cos: f64,
        sin: f64,
    },
    Ellipse {
        c: [f64; 2],
        half: [f64; 2],
        cos: f64,
        sin: f64,
    },
}

impl Shape {
    fn contains(&self, p: [f64; 2]) -> bool {
        let (c, half, cos, sin) = match self {
            Shape::Rect { c, half, cos, sin } | Shape::Ellipse { c, half, cos, sin } => {
                (c, half, cos, sin)
            }
        };
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        let (u, v) = (cos * dx + sin * dy, -sin * dx + cos * dy);
        match self {
            Shape::Rect { .. } => u.abs() <= half[0] && v.abs() <= half[1],
            Shape::Ellipse { .. } => (u / half[0]).powi(2) + (v / half[1]).powi(2) <= 1.0,
        }
    }
}

/// Renders a scene: the frame, a flat frame (a grey card of reflectance 0.5 under the same
/// light, same noise) and the truth.
///
/// The steps, in the order they draw from the seeded generator: the pose, the background
/// (`Background`), the occluder (`place_occluder`), the light (`Light`) and the Passport's
/// second page; then the chart is drawn (`ChartDrawing`) and rasterised (`rasterise`), the
/// flat frame lit alike (`flat_frame`), both blurred and made noisy (`add_noise`), and the
/// truth read off the same geometry (`true_patches`, `scene_truth`).
pub fn render(
    colours: &ChartColours,
    opts: &SceneOptions,
) -> Result<(Frame, Frame, SceneTruth), ChartError> {
    opts.check()?;
    let kind = colours.chart;
    let mut g = Gaussian::new(opts.seed);
    let (w, h) = (opts.width, opts.height);
    let (hom, rotation, tilt) = match opts.corners {
        Some(c) => (Homography::from_points(&kind.grid_corners(), &c)?, 0.0, 0.0),
        None => random_pose(kind, opts, &mut g)?,
    };
    let hinv = hom
        .inverse()
        .ok_or_else(|| ChartError::Geometry("the pose is singular".into()))?;
    let white = colours.white_rgb;
    let mut background = Background::new(white, w, h, opts.clutter, &mut g);
    if opts.texture > 0.0 {
        // Leaves sized in the chart's patch pitch at its centre.
        let c = kind.cell_centre(kind.cells() / 2);
        let (a, b) = (hom.apply(c), hom.apply([c[0] + 1.0, c[1]]));
        let pitch = (a[0] - b[0]).hypot(a[1] - b[1]);
        background.litter = Some(Litter::new(white, (opts.texture * pitch).max(2.0), &mut g));
    }
    let occluder = opts
        .occlusion
        .then(|| place_occluder(colours, &hom, &mut g));
    let centres: Vec<[f64; 2]> = (0..kind.cells())
        .map(|i| hom.apply(kind.cell_centre(i)))
        .collect();
    let light = Light::new(opts, g.uniform(), &centres)?;
    let second = opts.second_page.then(|| SecondPage::new(colours, &mut g));
    let drawing = ChartDrawing::new(colours, hom, hinv, occluder.as_ref(), second, opts);
    let data = rasterise(w, h, &background, &drawing, &light, opts.exposure);
    let mut frame = Frame::from_data(w, h, Layout::Rgb, data).expect("sized");
    let mut flat = flat_frame(w, h, white, &light, opts.exposure);
    if opts.blur > 0.0 {
        blur(&mut frame, opts.blur);
    }
    add_noise(&mut frame, opts, 0);
    add_noise(&mut flat, opts, 0x9e37_79b9);
    if let Some(look) = opts.look {
        apply_look(&mut frame, look, opts.white_level)?;
    }
    let patches = true_patches(colours, &hom, &light, occluder.as_ref(), opts);
    let truth = scene_truth(
        colours,
        opts,
        hom,
        (rotation, tilt),
        &light,
        &centres,
        patches,
    );
    Ok((frame, flat, truth))
}

/// A random colour of the surroundings: a grey of random lightness, tinted, below the white.
fn random_rgb(white: [f64; 3], g: &mut Gaussian) -> [f64; 3] {
    let base = 0.03 + 0.8 * g.uniform();
    let tint = [
        0.6 + 0.8 * g.uniform(),
        0.6 + 0.8 * g.uniform(),
        0.6 + 0.8 * g.uniform(),
    ];
    [0, 1, 2].map(|k| (white[k] * base * tint[k]).min(0.95 * white[k]))
}

/// The background: a smooth two-colour gradient under random shapes of random colours (the
/// last drawn on top).
struct Background {
    from: [f64; 3],
    to: [f64; 3],
    shapes: Vec<(Shape, [f64; 3])>,
    width: f64,
    height: f64,
    /// Leaf litter over the gradient, under the shapes ([`SceneOptions::texture`]).
    litter: Option<Litter>,
}

/// Leaf litter: a tiling of leaves, one per cell of a square grid of `cell` pixels, each at a
/// jittered point and elongated (1.5–3×) along its own direction (the nearest leaf in that
/// leaf's own stretched distance), a random warm colour (browns, ochres, dull greens) shaded
/// along its length and grained (±20 % over 2-pixel grains: a leaf's veins and speckle), the
/// gaps between leaves dark.
struct Litter {
    cell: f64,
    white: [f64; 3],
    key: u64,
}

impl Litter {
    fn new(white: [f64; 3], cell: f64, g: &mut Gaussian) -> Litter {
        Litter {
            cell,
            white,
            key: (g.uniform() * (1u64 << 52) as f64) as u64,
        }
    }

    /// Four uniform numbers in 0..1 drawn from the leaf of grid cell `(i, j)` (`salt` picks
    /// another set).
    fn draws(&self, i: i64, j: i64, salt: u64) -> [f64; 4] {
        let mut z = self.key
            ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ (j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
            ^ salt.wrapping_mul(0xd6e8_feb8_6659_fd93);
        [0; 4].map(|_| {
            // splitmix64
            z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            x ^= x >> 31;
            (x >> 11) as f64 / (1u64 << 53) as f64
        })
    }

    fn at(&self, px: f64, py: f64) -> [f64; 3] {
        let (u, v) = (px / self.cell, py / self.cell);
        let (ci, cj) = (u.floor() as i64, v.floor() as i64);
        let (mut d1, mut d2, mut best) = (f64::INFINITY, f64::INFINITY, (0, 0));
        for j in cj - 2..=cj + 2 {
            for i in ci - 2..=ci + 2 {
                let r = self.draws(i, j, 0);
                let (du, dv) = (u - i as f64 - r[0], v - j as f64 - r[1]);
                let a = std::f64::consts::TAU * r[3];
                let (along, across) = (du * a.cos() + dv * a.sin(), dv * a.cos() - du * a.sin());
                let d = along.hypot(across * (1.5 + 1.5 * self.draws(i, j, 3)[0]));
                if d < d1 {
                    d2 = d1;
                    d1 = d;
                    best = (i, j);
                } else if d < d2 {
                    d2 = d;
                }
            }
        }
        // The gap between two leaves: dark.
        if d2 - d1 < 0.08 {
            return self.white.map(|w| 0.02 * w);
        }
        let r = self.draws(best.0, best.1, 0);
        let s = self.draws(best.0, best.1, 1);
        let level = 0.04 + 0.4 * r[2] * r[2];
        let tint = [0.9 + 0.5 * s[0], 0.6 + 0.5 * s[1], 0.25 + 0.4 * s[2]];
        let a = std::f64::consts::TAU * r[3];
        let (du, dv) = (u - best.0 as f64 - r[0], v - best.1 as f64 - r[1]);
        let shade = (1.0 + 0.6 * s[3] * (du * a.cos() + dv * a.sin())).max(0.2);
        let grain = self.draws((px * 0.5).floor() as i64, (py * 0.5).floor() as i64, 2)[0];
        let shade = shade * (0.8 + 0.4 * grain);
        [0, 1, 2].map(|k| (self.white[k] * level * tint[k] * shade).min(0.95 * self.white[k]))
    }
}

impl Background {
    fn new(white: [f64; 3], w: usize, h: usize, clutter: usize, g: &mut Gaussian) -> Background {
        let from = random_rgb(white, g);
        let to = random_rgb(white, g);
        let mut shapes = Vec::with_capacity(clutter);
        let short = w.min(h) as f64;
        for _ in 0..clutter {
            let c = [g.uniform() * w as f64, g.uniform() * h as f64];
            let half = [
                short * (0.01 + 0.12 * g.uniform()),
                short * (0.01 + 0.12 * g.uniform()),
            ];
            let a = std::f64::consts::PI * g.uniform();
            let (cos, sin) = (a.cos(), a.sin());
            let shape = if g.uniform() < 0.5 {
                Shape::Rect { c, half, cos, sin }
            } else {
                Shape::Ellipse { c, half, cos, sin }
            };
            shapes.push((shape, random_rgb(white, g)));
        }
        Background {
            from,
            to,
            shapes,
            width: w as f64,
            height: h as f64,
            litter: None,
        }
    }

    /// The background's colour at pixel centre `(px, py)`.
    fn at(&self, px: f64, py: f64) -> [f64; 3] {
        if let Some((_, rgb)) = self.shapes.iter().rev().find(|(s, _)| s.contains([px, py])) {
            return *rgb;
        }
        if let Some(l) = &self.litter {
            return l.at(px, py);
        }
        let t = px / self.width * 0.7 + py / self.height * 0.3;
        [0, 1, 2].map(|k| self.from[k] * (1.0 - t) + self.to[k] * t)
    }
}

/// The occluder: an ellipse of skin-like colour over a random corner of the patch grid.
fn place_occluder(colours: &ChartColours, hom: &Homography, g: &mut Gaussian) -> (Shape, [f64; 3]) {
    let corner = colours.chart.grid_corners()[(g.uniform() * 4.0) as usize % 4];
    let c = hom.apply(corner);
    let pitch_px = {
        let a = hom.apply([corner[0], corner[1]]);
        let b = hom.apply([corner[0] + 1.0, corner[1]]);
        (a[0] - b[0]).hypot(a[1] - b[1])
    };
    let ang = std::f64::consts::PI * g.uniform();
    (
        Shape::Ellipse {
            c,
            half: [0.9 * pitch_px, 0.45 * pitch_px],
            cos: ang.cos(),
            sin: ang.sin(),
        },
        colours.rgb[1].map(|v| v * 0.8),
    )
}

/// The light: vignetting and a linear gradient in direction `dir` (radians), normalised to 1 on
/// average over the patch centres.
struct Light {
    width: f64,
    height: f64,
    vignetting: f64,
    gradient: f64,
    dir: f64,
    mean: f64,
}

impl Light {
    /// `dir_draw` is a uniform draw in (0, 1] (the direction is `τ · dir_draw`).
    fn new(opts: &SceneOptions, dir_draw: f64, centres: &[[f64; 2]]) -> Result<Light, ChartError> {
        let mut light = Light {
            width: opts.width as f64,
            height: opts.height as f64,
            vignetting: opts.vignetting,
            gradient: opts.gradient,
            dir: std::f64::consts::TAU * dir_draw,
            mean: 1.0,
        };
        let mean =
            centres.iter().map(|c| light.raw(c[0], c[1])).sum::<f64>() / centres.len() as f64;
        if !(mean > 0.0) {
            return Err(ChartError::Options(
                "the light is not positive on the chart (vignetting and gradient too strong)"
                    .into(),
            ));
        }
        light.mean = mean;
        Ok(light)
    }

    /// The light at `(x, y)` before normalisation.
    fn raw(&self, x: f64, y: f64) -> f64 {
        let (nx, ny) = (x / self.width - 0.5, y / self.height - 0.5);
        let r2 = (nx * nx + ny * ny) / 0.5;
        (1.0 - self.vignetting * r2)
            * (1.0 + self.gradient * (nx * self.dir.cos() + ny * self.dir.sin()))
    }

    /// The light at `(x, y)`.
    fn at(&self, x: f64, y: f64) -> f64 {
        self.raw(x, y) / self.mean
    }
}

/// The chart as drawn in the frame: its patches and body (and the Passport's second page), the
/// occluder over them, and the bounding box outside which only the background shows.
struct ChartDrawing<'a> {
    colours: &'a ChartColours,
    hinv: Homography,
    occluder: Option<&'a (Shape, [f64; 3])>,
    second: Option<SecondPage>,
    /// Every corner of the drawn body lies in front of the camera.
    in_front: bool,
    /// The drawn body's bounding box in the frame: x0, y0, x1, y1.
    bounds: [f64; 4],
    body_rgb: [f64; 3],
    /// Where a patch starts within its cell (chart units).
    gpos: f64,
}

impl<'a> ChartDrawing<'a> {
    fn new(
        colours: &'a ChartColours,
        hom: Homography,
        hinv: Homography,
        occluder: Option<&'a (Shape, [f64; 3])>,
        second: Option<SecondPage>,
        opts: &SceneOptions,
    ) -> ChartDrawing<'a> {
        let kind = colours.chart;
        // The drawn body: the chart's, and the second page's beside it.
        let drawn: Vec<[f64; 2]> = kind
            .body_corners()
            .iter()
            .flat_map(|c| {
                let mut v = vec![*c];
                if second.is_some() {
                    v.push([c[0] - SECOND_PAGE_SHIFT, c[1]]);
                }
                v
            })
            .collect();
        let in_front = drawn.iter().all(|c| hom.w(*c) > 0.0);
        let (bx0, by0, bx1, by1) = drawn.iter().map(|c| hom.apply(*c)).fold(
            (f64::MAX, f64::MAX, f64::MIN, f64::MIN),
            |(a, b, c, d), p| (a.min(p[0]), b.min(p[1]), c.max(p[0]), d.max(p[1])),
        );
        ChartDrawing {
            colours,
            hinv,
            occluder,
            second,
            in_front,
            bounds: [bx0, by0, bx1, by1],
            body_rgb: colours.white_rgb.map(|v| v * opts.body_reflectance),
            gpos: 0.5 * (1.0 - kind.patch_fraction()),
        }
    }

    /// Whether pixel centre `(px, py)` needs supersampling: within a pixel of the chart, or
    /// anywhere when there is an occluder.
    fn near(&self, px: f64, py: f64) -> bool {
        let [bx0, by0, bx1, by1] = self.bounds;
        let near = px >= bx0 - 1.0 && px <= bx1 + 1.0 && py >= by0 - 1.0 && py <= by1 + 1.0;
        near || self.occluder.is_some()
    }

    /// The reflected colour (camera RGB, unlit) at frame point `p` over background `bg`.
    fn at(&self, p: [f64; 2], bg: [f64; 3]) -> [f64; 3] {
        if let Some((o, rgb)) = self.occluder {
            if o.contains(p) {
                return *rgb;
            }
        }
        let [bx0, by0, bx1, by1] = self.bounds;
        if !self.in_front || p[0] < bx0 || p[0] > bx1 || p[1] < by0 || p[1] > by1 {
            return bg;
        }
        let kind = self.colours.chart;
        let (cols, rows) = (kind.columns() as f64, kind.rows() as f64);
        let m = kind.margin();
        let gpos = self.gpos;
        let q = self.hinv.apply(p);
        let left = if self.second.is_some() {
            -SECOND_PAGE_SHIFT - m
        } else {
            -m
        };
        if q[0] < left || q[1] < -m || q[0] > cols + m || q[1] > rows + m {
            return bg;
        }
        if let Some(page) = &self.second {
            if let Some(c) = page.at(q, gpos) {
                return c;
            }
        }
        if q[0] >= 0.0 && q[1] >= 0.0 && q[0] < cols && q[1] < rows {
            let (c, r) = (q[0].floor(), q[1].floor());
            let (fu, fv) = (q[0] - c, q[1] - r);
            if fu >= gpos && fu <= 1.0 - gpos && fv >= gpos && fv <= 1.0 - gpos {
                return self.colours.rgb[r as usize * kind.columns() + c as usize];
            }
        }
        self.body_rgb
    }

    /// The mean colour of pixel `(x, y)` over `bg`: 4 × 4 samples.
    fn supersampled(&self, x: usize, y: usize, bg: [f64; 3]) -> [f64; 3] {
        let mut acc = [0.0; 3];
        for sy in 0..4 {
            for sx in 0..4 {
                let p = [
                    x as f64 + (sx as f64 + 0.5) / 4.0,
                    y as f64 + (sy as f64 + 0.5) / 4.0,
                ];
                let c = self.at(p, bg);
                for k in 0..3 {
                    acc[k] += c[k] / 16.0;
                }
            }
        }
        acc
    }
}

/// The lit frame's RGB samples (row-major): the chart over the background, supersampled near
/// the chart, times the light and the exposure.
fn rasterise(
    w: usize,
    h: usize,
    background: &Background,
    drawing: &ChartDrawing,
    light: &Light,
    exposure: f64,
) -> Vec<f32> {
    let mut data = vec![0.0f32; w * h * 3];
    data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let bg = background.at(px, py);
            let v = if drawing.near(px, py) {
                drawing.supersampled(x, y, bg)
            } else {
                bg
            };
            let l = light.at(px, py) * exposure;
            for k in 0..3 {
                row[x * 3 + k] = (v[k] * l) as f32;
            }
        }
    });
    data
}

/// The flat frame: a grey card of reflectance 0.5 under the same light.
fn flat_frame(w: usize, h: usize, white: [f64; 3], light: &Light, exposure: f64) -> Frame {
    let mut flat = Frame::new(w, h, Layout::Rgb);
    flat.data
        .par_chunks_mut(w * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let l = light.at(x as f64 + 0.5, y as f64 + 0.5) * exposure * 0.5;
                for k in 0..3 {
                    row[x * 3 + k] = (white[k] * l) as f32;
                }
            }
        });
    flat
}

/// Seeded sensor noise (additive and shot, each row its own stream; `salt` tells frames of one
/// scene apart), then clipping at the white level.
fn add_noise(frame: &mut Frame, opts: &SceneOptions, salt: u64) {
    let seed = opts.seed.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ salt;
    let w = frame.width;
    frame
        .data
        .par_chunks_mut(w * 3)
        .enumerate()
        .for_each(|(y, row)| {
            let mut n = Gaussian::new(seed ^ (y as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            for v in row.iter_mut() {
                let s = (*v as f64).max(0.0);
                let sd = (opts.noise * opts.noise + opts.shot_noise * s).sqrt();
                let nv = if sd > 0.0 { s + sd * n.next() } else { s };
                *v = nv.min(opts.white_level) as f32;
            }
        });
}

/// Each patch as it truly is: its noise-free colour, lit and unlit, its centre, and whether the
/// occluder touches it (on a 5 × 5 grid over the patch's central half) or it clips.
fn true_patches(
    colours: &ChartColours,
    hom: &Homography,
    light: &Light,
    occluder: Option<&(Shape, [f64; 3])>,
    opts: &SceneOptions,
) -> Vec<TruePatch> {
    let kind = colours.chart;
    let side = kind.patch_fraction() * 0.5;
    (0..kind.cells())
        .map(|i| {
            let (c, r) = kind.cell(i);
            let cc = kind.cell_centre(i);
            let centre = hom.apply(cc);
            let rgb = colours.rgb[i].map(|v| v * opts.exposure);
            let l = light.at(centre[0], centre[1]);
            let rgb_lit = rgb.map(|v| v * l);
            let occluded = occluder.is_some_and(|(o, _)| {
                (0..=4).any(|a| {
                    (0..=4).any(|b| {
                        let p = [
                            cc[0] - side / 2.0 + side * a as f64 / 4.0,
                            cc[1] - side / 2.0 + side * b as f64 / 4.0,
                        ];
                        o.contains(hom.apply(p))
                    })
                })
            });
            TruePatch {
                label: kind.label(c, r),
                rgb,
                rgb_lit,
                xyz: colours.xyz[i],
                centre,
                occluded,
                clipped: rgb_lit.iter().any(|&v| v >= opts.white_level),
            }
        })
        .collect()
}

/// The truth file's value: the pose (`angles`: rotation and tilt in degrees), the options, the
/// light's non-uniformity over the patch `centres`, and the patches.
fn scene_truth(
    colours: &ChartColours,
    opts: &SceneOptions,
    hom: Homography,
    angles: (f64, f64),
    light: &Light,
    centres: &[[f64; 2]],
    patches: Vec<TruePatch>,
) -> SceneTruth {
    let kind = colours.chart;
    let (w, h) = (opts.width, opts.height);
    let body_q = kind.body_corners().map(|c| hom.apply(c));
    let lights: Vec<f64> = centres.iter().map(|c| light.at(c[0], c[1])).collect();
    let lmax = lights.iter().copied().fold(f64::MIN, f64::max);
    let lmin = lights.iter().copied().fold(f64::MAX, f64::min);
    SceneTruth {
        format: FORMAT.into(),
        version: 1,
        chart: kind,
        width: w,
        height: h,
        seed: opts.seed,
        homography: hom,
        corners: kind.grid_corners().map(|c| hom.apply(c)),
        body_corners: body_q,
        area_fraction: quad_area(&body_q) / (w * h) as f64,
        rotation_deg: angles.0,
        tilt_deg: angles.1,
        exposure: opts.exposure,
        white_level: opts.white_level,
        noise: opts.noise,
        shot_noise: opts.shot_noise,
        blur: opts.blur,
        vignetting: opts.vignetting,
        gradient: opts.gradient,
        light_nonuniformity: lmax / lmin,
        camera: colours.camera.clone(),
        illuminant: colours.illuminant.clone(),
        reflectances: colours.reflectances.clone(),
        patches,
        impostor: None,
    }
}

/// How far (chart units) the Passport's second page is shifted left of the classic page: the
/// chart's width, both margins and a hinge of half a pitch.
const SECOND_PAGE_SHIFT: f64 = 6.0 + 2.0 * 0.4 + 0.5;

/// The creative-enhancement page of a ColorChecker Passport, in the classic page's cell size
/// (6 × 4 cells shifted left by [`SECOND_PAGE_SHIFT`]): a warm-to-cool neutral row, skin tones,
/// a row of the classic page's colours in another order, and a grey ramp — the things that
/// could pass for a classic page.
struct SecondPage {
    cells: Vec<[f64; 3]>,
}

impl SecondPage {
    fn new(colours: &ChartColours, g: &mut Gaussian) -> SecondPage {
        let w = colours.white_rgb;
        let mut cells = Vec::with_capacity(24);
        // Row 1: near-neutrals from warm to cool at mid lightness.
        for k in 0..6 {
            let t = k as f64 / 5.0 - 0.5;
            cells.push([
                w[0] * 0.45 * (1.0 + 0.3 * t),
                w[1] * 0.45,
                w[2] * 0.45 * (1.0 - 0.3 * t),
            ]);
        }
        // Row 2: skin tones (the classic page's two, lightened and darkened).
        for k in 0..6 {
            let base = colours.rgb[k % 2];
            let f = 0.6 + 0.25 * k as f64;
            cells.push(base.map(|v| v * f));
        }
        // Row 3: six of the classic page's chromatic patches in a random order.
        let mut pick: Vec<usize> = (0..18.min(colours.rgb.len())).collect();
        for i in (1..pick.len()).rev() {
            let j = (g.uniform() * (i + 1) as f64) as usize % (i + 1);
            pick.swap(i, j);
        }
        for &i in pick.iter().take(6) {
            cells.push(colours.rgb[i]);
        }
        // Row 4: a grey ramp, dark to light (the classic page's runs light to dark).
        for k in 0..6 {
            let r = [0.03, 0.07, 0.13, 0.25, 0.45, 0.8][k];
            cells.push(w.map(|v| v * r));
        }
        SecondPage { cells }
    }

    /// The colour at chart point `q` when it falls on one of this page's patches.
    fn at(&self, q: [f64; 2], gpos: f64) -> Option<[f64; 3]> {
        let u = q[0] + SECOND_PAGE_SHIFT;
        if !(u >= 0.0 && q[1] >= 0.0 && u < 6.0 && q[1] < 4.0) {
            return None;
        }
        let (c, r) = (u.floor(), q[1].floor());
        let (fu, fv) = (u - c, q[1] - r);
        (fu >= gpos && fu <= 1.0 - gpos && fv >= gpos && fv <= 1.0 - gpos)
            .then(|| self.cells[r as usize * 6 + c as usize])
    }
}

/// Renders `frame` (linear, clipped at `white_level`) the way a camera writes a JPEG — sRGB
/// encoding, an S-shaped contrast curve, a saturation gain, 8-bit quantisation and JPEG
/// compression — and decodes it back with the plain sRGB transfer function.
pub(super) fn apply_look(
    frame: &mut Frame,
    look: CameraLook,
    white_level: f64,
) -> Result<(), ChartError> {
    use nsrm::srgb_oetf;
    let c = look.contrast;
    let curve = |x: f64| -> f64 {
        let e = srgb_oetf((x / white_level).clamp(0.0, 1.0));
        if c > 0.0 {
            let s = |t: f64| (c * (t - 0.5)).tanh();
            0.5 + 0.5 * s(e) / s(1.0)
        } else {
            e
        }
    };
    let mut bytes = Vec::with_capacity(frame.pixels() * 3);
    for px in frame.data.chunks_exact(3) {
        let e = [0, 1, 2].map(|k| curve(px[k] as f64));
        let m = (e[0] + e[1] + e[2]) / 3.0;
        for v in e {
            let v = (m + look.saturation * (v - m)).clamp(0.0, 1.0);
            bytes.push((v * 255.0).round() as u8);
        }
    }
    let (w, h) = (frame.width as u32, frame.height as u32);
    let bytes = if look.quality > 0 {
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, look.quality)
            .encode(&bytes, w, h, image::ExtendedColorType::Rgb8)
            .map_err(|e| ChartError::Invalid(format!("JPEG encoding: {e}")))?;
        image::load_from_memory_with_format(&jpeg, image::ImageFormat::Jpeg)
            .map_err(|e| ChartError::Invalid(format!("JPEG decoding: {e}")))?
            .to_rgb8()
            .into_raw()
    } else {
        bytes
    };
    let lut: Vec<f32> = (0..256)
        .map(|v| nsrm_io::display::srgb_eotf(v as f64 / 255.0) as f32)
        .collect();
    for (d, b) in frame.data.iter_mut().zip(bytes) {
        *d = lut[b as usize];
    }
    Ok(())
}

/// The synthetic families `chart rate` and the tests measure, beyond the detection envelope's
/// plain scenes: the difficulties of real photographs, and charts that are not the one asked
/// for (every one of which must be refused).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// The envelope's scenes (linear camera RGB).
    Envelope,
    /// The envelope's scenes through a camera JPEG rendering ([`CameraLook`]).
    Jpeg,
    /// The patch grid filling the frame (1–4 % from its edges), no surround; a camera JPEG
    /// rendering half of the time.
    Fill,
    /// Small charts (3–8 % of the frame) with a corner hidden.
    Small,
    /// A ColorChecker Passport with its second page open beside the classic page.
    Passport,
    /// Negative: a SpyderCHECKR-24-like chart (greys in two columns, the colours in another
    /// order); for an SG, another make's 14 × 10 chart (no grey border, a twenty-step ramp in
    /// two columns, the SG's colours in another order).
    Spyder,
    /// Negative: a grid of random patch colours.
    Random,
    /// Negative: the classic page's greys in place but its colours in another order (another
    /// chart made of the same materials); for an SG, its near-neutrals in place, its colours
    /// deranged.
    Shuffled,
    // (New families go last: the discriminant seeds each family's draws.)
    /// Stronger perspective than the envelope: tilt 30–50°, the chart covering 10–40 %.
    Tilt,
    /// The chart's body as dark as its black patch (0.8–1.2×), 2–5 stops under clipping and
    /// blurred (σ 0.8–2 px): the dark patches merge with the frame around them.
    BlackFrame,
    /// A wide-angle camera close to the chart: tilt 30–40°, the camera as close as it takes
    /// for the patch scale to vary 1.6–2.2× across the chart ([`SceneOptions::perspective`],
    /// drawn uniformly), the whole chart in the frame (15–45 % of it), nothing over it, the
    /// body darker than the black patch (0.35–0.6×) so that every cell can be seen.
    Wide,
    /// Negative: one chart nested in another ([`nested`]) — for a CC24, a ColorChecker Digital
    /// SG-like 14 × 10 chart holding the classic 24 colours in its E2–J5 block, as the SG does;
    /// for an SG, a CC24 whose 24 cells are the SG's E2–J5 block.
    Nested,
    /// Negative: a Datacolor SpyderCHECKR 24 ([`spyder24`]) — the classic 24 colours with the
    /// first and third rows reversed (the second row and the grey ramp in place); for an SG,
    /// that chart made of the SG's E2–J5 block.
    Spyder24,
    /// A strongly graded, saturated product-style photograph: a clean chart (tilt up to 15°,
    /// 10–35 % of the frame) through a strong camera look — contrast curve 3–5, saturation
    /// ×1.6–2.2, JPEG quality 85–95 ([`CameraLook`]).
    Graded,
    /// A very noisy frame (a small sensor at a very high ISO): a large, frontal chart (35–60 %
    /// of the frame, tilt up to 10°), 0.5–2 stops under clipping, additive noise σ 0.03–0.07 of
    /// the white level plus shot noise (0.003–0.008 per unit of signal), blur σ 0.5–1.2 px; a
    /// camera JPEG half of the time.
    Noisy,
    /// A tiny chart on textured ground: 0.8–1.4 % of the frame (a CC24 at 1200 × 800 has about
    /// 17–23 px between patch centres), on leaf litter whose leaves are 0.8–3 patch pitches
    /// across ([`SceneOptions::texture`]), no other clutter; a camera JPEG half of the time.
    Litter,
}

impl Family {
    /// Every family, in the order `chart rate` lists them.
    pub const ALL: [Family; 16] = [
        Family::Envelope,
        Family::Jpeg,
        Family::Fill,
        Family::Small,
        Family::Passport,
        Family::Tilt,
        Family::BlackFrame,
        Family::Wide,
        Family::Spyder,
        Family::Random,
        Family::Shuffled,
        Family::Nested,
        Family::Spyder24,
        Family::Graded,
        Family::Noisy,
        Family::Litter,
    ];

    /// The family's name (`envelope`, `jpeg`, …), as `chart rate --family` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Family::Envelope => "envelope",
            Family::Jpeg => "jpeg",
            Family::Fill => "fill",
            Family::Small => "small",
            Family::Passport => "passport",
            Family::Tilt => "tilt",
            Family::BlackFrame => "black-frame",
            Family::Wide => "wide",
            Family::Spyder => "spyder",
            Family::Random => "random",
            Family::Shuffled => "shuffled",
            Family::Nested => "nested",
            Family::Spyder24 => "spyder24",
            Family::Graded => "graded",
            Family::Noisy => "noisy",
            Family::Litter => "litter",
        }
    }

    /// The family named `s` (its [`Family::name`]), if any.
    pub fn parse(s: &str) -> Option<Family> {
        Family::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s.trim()))
    }

    /// True for the charts that are not the one asked for: any detection is wrong.
    pub fn negative(self) -> bool {
        matches!(
            self,
            Family::Spyder | Family::Random | Family::Shuffled | Family::Nested | Family::Spyder24
        )
    }

    /// The colours and options of scene `seed` of this family (a negative's impostor in the
    /// layout of `colours`' chart; the truth of a negative scene names the cells of the
    /// impostor, not that chart's).
    pub fn scene(
        self,
        colours: &ChartColours,
        width: usize,
        height: usize,
        seed: u64,
    ) -> (ChartColours, SceneOptions) {
        let mut o = SceneOptions::envelope(colours, width, height, seed);
        let mut g = Gaussian::new(seed ^ 0xfa31_17e5_u64.wrapping_mul(self as u64 + 1));
        let look = |g: &mut Gaussian| CameraLook {
            contrast: 0.5 + 2.5 * g.uniform(),
            saturation: 1.0 + 0.5 * g.uniform(),
            quality: 70 + (25.0 * g.uniform()) as u8,
        };
        let mut c = colours.clone();
        match self {
            Family::Envelope => {}
            Family::Jpeg => o.look = Some(look(&mut g)),
            Family::Fill => {
                o.corners = Some(fill_corners(colours.chart, width, height, &mut g));
                if g.uniform() < 0.5 {
                    o.look = Some(look(&mut g));
                }
            }
            Family::Small => {
                o.min_area = 0.03;
                o.max_area = 0.08;
                o.occlusion = true;
            }
            Family::Passport => {
                o.second_page = true;
                o.max_area = 0.25;
                if g.uniform() < 0.5 {
                    o.look = Some(look(&mut g));
                }
            }
            Family::Tilt => {
                o.min_tilt_deg = 30.0;
                o.max_tilt_deg = 50.0;
                o.min_area = 0.1;
            }
            Family::Wide => {
                o.min_tilt_deg = 30.0;
                o.max_tilt_deg = 40.0;
                o.min_area = 0.15;
                o.max_area = 0.45;
                o.perspective = Some(1.6 + 0.6 * g.uniform());
                // A body darker than the black patch (a Classic's frame is), so that every
                // cell can be seen as a patch: the envelope's body (0.035) is the black
                // patch's own reflectance, which hides it.
                o.body_reflectance = black_patch(colours) * (0.35 + 0.25 * g.uniform());
            }
            Family::BlackFrame => {
                o.body_reflectance = black_patch(colours) * (0.8 + 0.4 * g.uniform());
                let brightest = colours.rgb.iter().flatten().copied().fold(0.0, f64::max);
                o.exposure = 2f64.powf(-2.0 - 3.0 * g.uniform()) / brightest;
                o.blur = 0.8 + 1.2 * g.uniform();
                if g.uniform() < 0.5 {
                    o.look = Some(look(&mut g));
                }
            }
            Family::Graded => {
                o.max_tilt_deg = 15.0;
                o.min_area = 0.1;
                o.max_area = 0.35;
                o.look = Some(CameraLook {
                    contrast: 3.0 + 2.0 * g.uniform(),
                    saturation: 1.6 + 0.6 * g.uniform(),
                    quality: 85 + (10.0 * g.uniform()) as u8,
                });
            }
            Family::Noisy => {
                o.max_tilt_deg = 10.0;
                o.min_area = 0.35;
                o.max_area = 0.6;
                let brightest = colours.rgb.iter().flatten().copied().fold(0.0, f64::max);
                o.exposure = 2f64.powf(-0.5 - 1.5 * g.uniform()) / brightest;
                o.noise = 0.03 + 0.04 * g.uniform();
                o.shot_noise = 0.003 + 0.005 * g.uniform();
                o.blur = 0.5 + 0.7 * g.uniform();
                if g.uniform() < 0.5 {
                    o.look = Some(look(&mut g));
                }
            }
            Family::Litter => {
                o.min_area = 0.008;
                o.max_area = 0.014;
                o.clutter = 0;
                o.texture = 0.8 + 2.2 * g.uniform();
                if g.uniform() < 0.5 {
                    o.look = Some(look(&mut g));
                }
            }
            Family::Spyder
            | Family::Random
            | Family::Shuffled
            | Family::Nested
            | Family::Spyder24 => {
                c = impostor(colours, self, &mut g);
                if g.uniform() < 0.5 {
                    o.look = Some(look(&mut g));
                }
            }
        }
        (c, o)
    }
}

/// The darkest patch's G relative to the white's: the black patch's reflectance.
fn black_patch(colours: &ChartColours) -> f64 {
    colours
        .rgb
        .iter()
        .map(|p| p[1] / colours.white_rgb[1])
        .fold(f64::INFINITY, f64::min)
}

/// Grid corners (first patch first, clockwise) that fill a `width × height` frame to within
/// 1–4 % of its edges, upright or upside down, each corner moved by up to 2 % (perspective).
fn fill_corners(kind: ChartKind, width: usize, height: usize, g: &mut Gaussian) -> [[f64; 2]; 4] {
    let (w, h) = (width as f64, height as f64);
    let aspect = kind.columns() as f64 / kind.rows() as f64;
    let m = (0.01 + 0.03 * g.uniform()) * w.min(h);
    let (mut gw, mut gh) = (w - 2.0 * m, h - 2.0 * m);
    if gw / gh > aspect {
        gw = gh * aspect;
    } else {
        gh = gw / aspect;
    }
    let (x0, y0) = ((w - gw) / 2.0, (h - gh) / 2.0);
    let mut q = [[x0, y0], [x0 + gw, y0], [x0 + gw, y0 + gh], [x0, y0 + gh]];
    for p in q.iter_mut() {
        let j = 0.02 * w.min(h);
        p[0] = (p[0] + j * (2.0 * g.uniform() - 1.0)).clamp(1.0, w - 1.0);
        p[1] = (p[1] + j * (2.0 * g.uniform() - 1.0)).clamp(1.0, h - 1.0);
    }
    if g.uniform() < 0.5 {
        q.rotate_left(2);
    }
    q
}

/// The colours of a chart that is not the one simulated (see [`Family`]): [`nested`] and
/// [`spyder24`], or in its layout for a CC24 ([`cc24_impostor`]) or an SG ([`sg_impostor`]).
fn impostor(colours: &ChartColours, family: Family, g: &mut Gaussian) -> ChartColours {
    match (family, colours.chart) {
        (Family::Nested, _) => nested(colours, g),
        (Family::Spyder24, _) => spyder24(colours, g),
        (_, ChartKind::Cc24 | ChartKind::Spyder24) => cc24_impostor(colours, family, g),
        (_, ChartKind::Sg) => sg_impostor(colours, family, g),
    }
}

/// A random patch colour relative to the white `w` ([`Family::Random`]'s cells): a level of
/// 0.03–0.88, each channel 0.3–1.7 times it, at most 0.95 of the white.
fn random_colour(w: [f64; 3], g: &mut Gaussian) -> [f64; 3] {
    let base = 0.03 + 0.85 * g.uniform();
    [0, 1, 2].map(|k| w[k] * (base * (0.3 + 1.4 * g.uniform())).min(0.95))
}

/// The SG's cells that hold the classic 24 colours: its block E2–J5 (columns E–J, rows 2–5),
/// SG index of CC24 cell `i`.
fn sg_block(i: usize) -> usize {
    let (cc24, sg) = (ChartKind::Cc24, ChartKind::Sg);
    let (c, r) = cc24.cell(i);
    (r + 1) * sg.columns() + c + 4
}

/// [`Family::Nested`]'s chart: for a CC24's `colours`, an SG-like chart — the alternating
/// white, grey and black border of the SG, the classic 24 in its E2–J5 block, random colours
/// elsewhere (as [`Family::Random`]'s); for an SG's, a CC24 made of the SG's E2–J5 block.
fn nested(colours: &ChartColours, g: &mut Gaussian) -> ChartColours {
    let w = colours.white_rgb;
    let (cc24, sg) = (ChartKind::Cc24, ChartKind::Sg);
    match colours.chart {
        ChartKind::Sg => ChartColours {
            chart: cc24,
            rgb: (0..cc24.cells())
                .map(|i| colours.rgb[sg_block(i)])
                .collect(),
            xyz: (0..cc24.cells())
                .map(|i| colours.xyz[sg_block(i)])
                .collect(),
            ..colours.clone()
        },
        ChartKind::Cc24 | ChartKind::Spyder24 => {
            let (cols, rows) = (sg.columns(), sg.rows());
            let mut rgb: Vec<[f64; 3]> = (0..sg.cells())
                .map(|i| {
                    let (c, r) = sg.cell(i);
                    if c == 0 || r == 0 || c == cols - 1 || r == rows - 1 {
                        let level = [0.9, 0.2, 0.03][(c + r) % 3];
                        w.map(|v| v * level)
                    } else {
                        random_colour(w, g)
                    }
                })
                .collect();
            let mut xyz = vec![[0.0; 3]; sg.cells()];
            for i in 0..cc24.cells() {
                rgb[sg_block(i)] = colours.rgb[i];
                xyz[sg_block(i)] = colours.xyz[i];
            }
            ChartColours {
                chart: sg,
                rgb,
                xyz,
                ..colours.clone()
            }
        }
    }
}

/// [`Family::Spyder24`]'s chart: the Datacolor SpyderCHECKR 24 holds the classic 24 colours with
/// its first and third rows reversed (bluish green … dark skin; cyan … blue), the second row and
/// the grey ramp as the classic's — 12 of its 24 cells agree with a CC24 read the same way up
/// (its colours still miss the CC24's by a median ΔE00 of 15.9–23.0 after the best map, 60
/// scenes: refused by colour, the limit being 8). For an SG's colours, that chart
/// made of the SG's E2–J5 block (the CC24 of [`nested`], so reordered). For a SpyderCHECKR's
/// colours, the same swap undone: a classic ColorChecker, the other make.
fn spyder24(colours: &ChartColours, g: &mut Gaussian) -> ChartColours {
    if colours.chart == ChartKind::Sg {
        return spyder24(&nested(colours, g), g);
    }
    let mut c = colours.clone();
    for i in 0..c.rgb.len() {
        let j = spyder24_cell(i);
        c.rgb[i] = colours.rgb[j];
        c.xyz[i] = colours.xyz[j];
    }
    c
}

/// The SpyderCHECKR 24 cell that holds the colour of classic cell `i` (and the classic cell of
/// SpyderCHECKR cell `i`: the map is its own inverse): the top and third rows reversed, the
/// second row and the grey ramp in place.
pub(crate) fn spyder24_cell(i: usize) -> usize {
    let (c, r) = (i % 6, i / 6);
    if r % 2 == 0 {
        r * 6 + 5 - c
    } else {
        i
    }
}

/// Shuffles `v` in place (Fisher–Yates on the seeded generator).
fn shuffle(v: &mut [usize], g: &mut Gaussian) {
    for i in (1..v.len()).rev() {
        let j = (g.uniform() * (i + 1) as f64) as usize % (i + 1);
        v.swap(i, j);
    }
}

/// Reorders `v` so that no element stays where it was (a derangement, by shuffling until none
/// does; `v` needs two elements).
fn derange(v: &mut [usize], g: &mut Gaussian) {
    let orig = v.to_vec();
    loop {
        shuffle(v, g);
        if v.iter().zip(&orig).all(|(a, b)| a != b) {
            break;
        }
    }
}

/// Whether camera RGB `rgb` is near-neutral: its channels, each relative to the white's, differ
/// by less than [`NEUTRAL_SPREAD`] of the largest. (The SG under D65 seen by the D5100: its 59
/// greys, Lab chroma ≤ 2.2, spread at most 0.070; K4, chroma 7.9, 0.073 — near-neutral too;
/// the other colours, chroma ≥ 8.5, at least 0.14.)
fn near_neutral(rgb: [f64; 3], white: [f64; 3]) -> bool {
    let v = [0, 1, 2].map(|k| rgb[k] / white[k]);
    let hi = v.iter().copied().fold(f64::MIN, f64::max);
    let lo = v.iter().copied().fold(f64::MAX, f64::min);
    hi > 0.0 && (hi - lo) < NEUTRAL_SPREAD * hi
}

/// See [`near_neutral`].
const NEUTRAL_SPREAD: f64 = 0.1;

/// An impostor in the SG's 14 × 10 layout (`Random` is [`cc24_impostor`]'s, which fills any
/// layout):
/// * `Spyder`: another make's 140-patch chart — no alternating grey border; the two right
///   columns a twenty-step grey ramp (white at the top of the first, black at the bottom of
///   the second); the other 120 cells the SG's chromatic colours in a random order (each once
///   before any repeats);
/// * `Shuffled`: the SG's own cells, its near-neutrals ([`near_neutral`]: the border, the
///   central ramp) in place and its chromatic cells deranged — another chart of the same
///   materials; 60 of the 140 cells are right, so a reading by the median colour difference
///   alone could take it for an SG.
fn sg_impostor(colours: &ChartColours, family: Family, g: &mut Gaussian) -> ChartColours {
    let kind = colours.chart;
    let w = colours.white_rgb;
    let mut c = colours.clone();
    let chromatic: Vec<usize> = (0..kind.cells())
        .filter(|&i| !near_neutral(colours.rgb[i], w))
        .collect();
    match family {
        Family::Spyder => {
            let (cols, rows) = (kind.columns(), kind.rows());
            let steps = 2 * rows;
            let mut pick = chromatic.clone();
            shuffle(&mut pick, g);
            let mut k = 0;
            for r in 0..rows {
                for col in 0..cols {
                    let i = r * cols + col;
                    c.rgb[i] = if col >= cols - 2 {
                        // Geometric from 0.9 down to 0.03.
                        let step = (col - (cols - 2)) * rows + r;
                        let t = step as f64 / (steps - 1) as f64;
                        w.map(|v| v * 0.9 * (0.03f64 / 0.9).powf(t))
                    } else {
                        k += 1;
                        colours.rgb[pick[(k - 1) % pick.len()]]
                    };
                }
            }
        }
        Family::Shuffled => {
            let mut pick = chromatic.clone();
            derange(&mut pick, g);
            for (&i, &p) in chromatic.iter().zip(&pick) {
                c.rgb[i] = colours.rgb[p];
            }
        }
        _ => return cc24_impostor(colours, family, g),
    }
    c
}

/// The colours of a chart that is not a CC24 (see [`Family`]), in a CC24 layout (`Random`:
/// in any layout).
fn cc24_impostor(colours: &ChartColours, family: Family, g: &mut Gaussian) -> ChartColours {
    let kind = colours.chart;
    let n = kind.cells();
    let w = colours.white_rgb;
    let mut c = colours.clone();
    let chromatic: Vec<usize> = (0..n.min(18)).collect();
    let shuffle = |v: &mut Vec<usize>, g: &mut Gaussian| {
        for i in (1..v.len()).rev() {
            let j = (g.uniform() * (i + 1) as f64) as usize % (i + 1);
            v.swap(i, j);
        }
    };
    match family {
        Family::Spyder => {
            // Columns 5 and 6: an eight-step grey ramp, white at the top of column 5;
            // columns 1–4: sixteen of the classic colours in another order.
            let ramp = [0.9, 0.7, 0.55, 0.42, 0.3, 0.2, 0.1, 0.03];
            let mut pick = chromatic.clone();
            shuffle(&mut pick, g);
            let mut k = 0;
            for r in 0..kind.rows() {
                for col in 0..kind.columns() {
                    let i = r * kind.columns() + col;
                    c.rgb[i] = if col >= kind.columns() - 2 {
                        let step = (col - (kind.columns() - 2)) * kind.rows() + r;
                        w.map(|v| v * ramp[step.min(7)])
                    } else {
                        k += 1;
                        colours.rgb[pick[(k - 1) % pick.len()]]
                    };
                }
            }
        }
        Family::Random => {
            for v in c.rgb.iter_mut() {
                *v = random_colour(w, g);
            }
        }
        Family::Shuffled => {
            // A derangement of the chromatic cells: none keeps its colour.
            let mut pick = chromatic.clone();
            loop {
                shuffle(&mut pick, g);
                if pick.iter().enumerate().all(|(i, &p)| i != p) {
                    break;
                }
            }
            for (i, &p) in pick.iter().enumerate() {
                c.rgb[i] = colours.rgb[p];
            }
        }
        _ => {}
    }
    c
}

/// Gaussian blur of every channel (imageproc's separable filter).
fn blur(frame: &mut Frame, sigma: f64) {
    let (w, h) = (frame.width as u32, frame.height as u32);
    let img: image::ImageBuffer<image::Rgb<f32>, Vec<f32>> =
        image::ImageBuffer::from_raw(w, h, std::mem::take(&mut frame.data)).expect("sized");
    let out = imageproc::filter::gaussian_blur_f32(&img, sigma as f32);
    frame.data = out.into_raw();
}

#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
