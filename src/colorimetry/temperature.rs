//! Colour temperature: the Planckian locus and CIE daylight as chromaticities, correlated colour
//! temperature (CCT) of a chromaticity by Robertson's method as the DNG SDK computes it
//! (`dng_temperature`), the two-illuminant weight of the DNG specification (linear in inverse
//! temperature, clamped), and the DNG fixed-point iteration that finds the chromaticity of a
//! camera neutral (`NeutralToXY`), over any map from XYZ to camera RGB.
//!
//! A *named temperature* (`apply --white 4000`) is a Planckian light below 4000 K and CIE daylight
//! from 4000 K up ([`temperature_xy`]).

use super::spaces::Mat3;

/// Errors from temperatures and chromaticities.
#[derive(Debug, thiserror::Error)]
pub enum TemperatureError {
    /// A temperature or chromaticity out of the range handled (the caller's mistake).
    #[error("{0}")]
    Range(String),
    /// The fixed-point iteration of a neutral's chromaticity left the valid range.
    #[error("the chromaticity of the camera neutral {neutral:?} could not be found: {why}")]
    Neutral {
        /// The camera neutral (RGB) whose chromaticity was sought.
        neutral: [f64; 3],
        /// Why the iteration failed.
        why: String,
    },
}

/// The range of temperatures handled, in kelvin (Robertson's table spans 1667 K to infinity; CIE
/// daylight is defined from 4000 K to 25000 K).
pub(crate) const MIN_CCT: f64 = 1000.0;
pub(crate) const MAX_CCT: f64 = 25000.0;
/// Below this a bare temperature names a Planckian light, from it up CIE daylight.
pub(crate) const DAYLIGHT_FROM: f64 = 4000.0;

/// Second radiation constant c2 = hc/k (m·K), CODATA 2018 (what CIE 15:2018 uses).
const C2: f64 = 1.438_776_877e-2;

/// CIE 1931 chromaticity `(x, y)` of a Planckian radiator at `t` kelvin, integrated over the
/// built-in CIE 1931 2° colour-matching functions ([`super::observer`], 360–830 nm, 1 nm).
pub(crate) fn planckian_xy(t: f64) -> Result<[f64; 2], TemperatureError> {
    check_t(t, MIN_CCT, 100_000.0)?;
    let cmf = super::observer::cie1931();
    let mut xyz = [0.0; 3];
    for (i, &w) in cmf.wavelengths.iter().enumerate() {
        let l = w * 1e-9;
        let m = l.powi(-5) / ((C2 / (l * t)).exp_m1());
        for k in 0..3 {
            xyz[k] += m * cmf.values[k][i];
        }
    }
    let s: f64 = xyz.iter().sum();
    Ok([xyz[0] / s, xyz[1] / s])
}

/// CIE 1931 chromaticity of CIE daylight at correlated colour temperature `t` (CIE 15, 4000 K to
/// 25000 K). `t` is taken as given (D65 is 6504 K: 6500 × 1.4388/1.4380).
pub(crate) fn daylight_xy(t: f64) -> Result<[f64; 2], TemperatureError> {
    check_t(t, DAYLIGHT_FROM, MAX_CCT)?;
    let x = if t <= 7000.0 {
        -4.6070e9 / t.powi(3) + 2.9678e6 / t.powi(2) + 0.09911e3 / t + 0.244063
    } else {
        -2.0064e9 / t.powi(3) + 1.9018e6 / t.powi(2) + 0.24748e3 / t + 0.237040
    };
    Ok([x, -3.0 * x * x + 2.870 * x - 0.275])
}

/// The chromaticity a bare temperature names: Planckian below 4000 K, CIE daylight from
/// it up.
pub fn temperature_xy(t: f64) -> Result<[f64; 2], TemperatureError> {
    check_t(t, MIN_CCT, MAX_CCT)?;
    if t < DAYLIGHT_FROM {
        planckian_xy(t)
    } else {
        daylight_xy(t)
    }
}

fn check_t(t: f64, lo: f64, hi: f64) -> Result<(), TemperatureError> {
    if t.is_finite() && (lo..=hi).contains(&t) {
        Ok(())
    } else {
        Err(TemperatureError::Range(format!(
            "colour temperature {t} K is outside {lo}..={hi} K"
        )))
    }
}

/// Robertson's isotemperature lines (Robertson 1968, as tabulated in the DNG SDK): reciprocal
/// megakelvin, CIE 1960 u, v, and the slope of the isotherm.
const ROBERTSON: [[f64; 4]; 31] = [
    [0.0, 0.18006, 0.26352, -0.24341],
    [10.0, 0.18066, 0.26589, -0.25479],
    [20.0, 0.18133, 0.26846, -0.26876],
    [30.0, 0.18208, 0.27119, -0.28539],
    [40.0, 0.18293, 0.27407, -0.30470],
    [50.0, 0.18388, 0.27709, -0.32675],
    [60.0, 0.18494, 0.28021, -0.35156],
    [70.0, 0.18611, 0.28342, -0.37915],
    [80.0, 0.18740, 0.28668, -0.40955],
    [90.0, 0.18880, 0.28997, -0.44278],
    [100.0, 0.19032, 0.29326, -0.47888],
    [125.0, 0.19462, 0.30141, -0.58204],
    [150.0, 0.19962, 0.30921, -0.70471],
    [175.0, 0.20525, 0.31647, -0.84901],
    [200.0, 0.21142, 0.32312, -1.0182],
    [225.0, 0.21807, 0.32909, -1.2168],
    [250.0, 0.22511, 0.33439, -1.4512],
    [275.0, 0.23247, 0.33904, -1.7298],
    [300.0, 0.24010, 0.34308, -2.0637],
    [325.0, 0.24792, 0.34655, -2.4681],
    [350.0, 0.25591, 0.34951, -2.9641],
    [375.0, 0.26400, 0.35200, -3.5814],
    [400.0, 0.27218, 0.35407, -4.3633],
    [425.0, 0.28039, 0.35577, -5.3762],
    [450.0, 0.28863, 0.35714, -6.7262],
    [475.0, 0.29685, 0.35823, -8.5955],
    [500.0, 0.30505, 0.35907, -11.324],
    [525.0, 0.31320, 0.35968, -15.628],
    [550.0, 0.32129, 0.36011, -23.325],
    [575.0, 0.32931, 0.36038, -40.770],
    [600.0, 0.33724, 0.36051, -116.45],
];

/// Correlated colour temperature (K) of a chromaticity by Robertson's method, step for step as
/// the DNG SDK's `dng_temperature::Set_xy` (so a DCP reader and nsrm weight a white the same).
/// Chromaticities beyond the table's hottest line give its end (≈ 1667 K); an `x, y` that is not
/// a chromaticity is refused.
pub fn cct(xy: [f64; 2]) -> Result<f64, TemperatureError> {
    let [x, y] = xy;
    let den = 1.5 - x + 6.0 * y;
    if !(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0 && x + y < 1.0 && den > 0.0) {
        return Err(TemperatureError::Range(format!(
            "({x}, {y}) is not a chromaticity"
        )));
    }
    let u = 2.0 * x / den;
    let v = 3.0 * y / den;
    let (mut last_dt, mut t) = (0.0, None);
    for i in 1..ROBERTSON.len() {
        let [r, tu, tv, slope] = ROBERTSON[i];
        let len = (1.0 + slope * slope).sqrt();
        let (du, dv) = (1.0 / len, slope / len);
        let mut dt = -(u - tu) * dv + (v - tv) * du;
        if dt <= 0.0 || i == ROBERTSON.len() - 1 {
            if dt > 0.0 {
                dt = 0.0;
            }
            dt = -dt;
            let f = if i == 1 { 0.0 } else { dt / (last_dt + dt) };
            t = Some(1.0e6 / (ROBERTSON[i - 1][0] * f + r * (1.0 - f)));
            break;
        }
        last_dt = dt;
    }
    let t = t.expect("the loop ends at the last line");
    Ok(if t.is_finite() { t } else { f64::INFINITY })
}

/// The weight of the first of two calibration illuminants (temperatures `t1 < t2`) at temperature
/// `t`, by the DNG rule: linear in `1/t` between them, clamped to 1 below `t1` and 0 above `t2`.
pub fn dng_weight(t: f64, t1: f64, t2: f64) -> f64 {
    if t <= t1 {
        1.0
    } else if t >= t2 {
        0.0
    } else {
        ((1.0 / t - 1.0 / t2) / (1.0 / t1 - 1.0 / t2)).clamp(0.0, 1.0)
    }
}

/// XYZ (`Y = 1`) of a chromaticity.
pub(crate) fn xy_to_xyz(xy: [f64; 2]) -> [f64; 3] {
    super::spaces::xy_to_xyz(xy)
}

/// Chromaticity of an XYZ colour (`None` for a non-positive sum or a non-finite value).
pub(crate) fn xyz_to_xy(xyz: [f64; 3]) -> Option<[f64; 2]> {
    let s = xyz[0] + xyz[1] + xyz[2];
    (s.is_finite() && s > 0.0).then(|| [xyz[0] / s, xyz[1] / s])
}

/// D50 as the DNG SDK names it (`D50_xy`), where its neutral iteration starts.
pub const D50_XY: [f64; 2] = [0.3457, 0.3585];

/// The chromaticity of a camera neutral by the DNG fixed-point iteration (`NeutralToXY`): start at
/// D50, map the neutral to XYZ with the camera model interpolated for the current guess's
/// temperature (`camera_to_xyz(neutral, weight)`), take that XYZ's chromaticity, and repeat until
/// it moves less than 1e-7, at most 30 passes (the last one averaged, as the SDK does).
pub fn neutral_to_xy(
    neutral: [f64; 3],
    temperatures: [f64; 2],
    mut camera_to_xyz: impl FnMut([f64; 3], f64) -> Option<[f64; 3]>,
) -> Result<[f64; 2], TemperatureError> {
    let bad = |why: &str| TemperatureError::Neutral {
        neutral,
        why: why.to_string(),
    };
    if !neutral.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Err(bad("each channel must be finite and > 0"));
    }
    let mut last = D50_XY;
    for pass in 0..30 {
        let w = dng_weight(cct(last)?, temperatures[0], temperatures[1]);
        let xyz = camera_to_xyz(neutral, w).ok_or_else(|| bad("the model has no inverse there"))?;
        let mut next = xyz_to_xy(xyz).ok_or_else(|| bad("it maps to a non-positive XYZ"))?;
        if !(next[0] > 0.0 && next[1] > 0.0 && next[0] + next[1] < 1.0) {
            return Err(bad("it maps outside the chromaticity diagram"));
        }
        if (next[0] - last[0]).abs() + (next[1] - last[1]).abs() < 1e-7 {
            return Ok(next);
        }
        if pass == 29 {
            next = [(last[0] + next[0]) / 2.0, (last[1] + next[1]) / 2.0];
        }
        last = next;
    }
    Ok(last)
}

/// Bradford adaptation from the white `src` to the white `dst` (XYZ, any scale: the matrix maps
/// `src` to `dst` scaled to `src`'s Y).
pub fn bradford_between(src: [f64; 3], dst: [f64; 3]) -> Mat3 {
    let s = [src[0] / src[1], 1.0, src[2] / src[1]];
    let d = [dst[0] / dst[1], 1.0, dst[2] / dst[1]];
    super::spaces::bradford(s, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_lights_have_their_published_chromaticities() {
        // CIE 15: illuminant A (2856 K) x, y = 0.44757, 0.40745; D65 0.31271, 0.32902 at 6504 K;
        // D50 0.34567, 0.35850 at 5003 K.
        let a = planckian_xy(2856.0).unwrap();
        assert!(
            (a[0] - 0.44757).abs() < 2e-4 && (a[1] - 0.40745).abs() < 2e-4,
            "{a:?}"
        );
        let d65 = daylight_xy(6504.0).unwrap();
        assert!(
            (d65[0] - 0.31271).abs() < 1e-4 && (d65[1] - 0.32902).abs() < 1e-4,
            "{d65:?}"
        );
        let d50 = daylight_xy(5003.0).unwrap();
        assert!(
            (d50[0] - 0.34567).abs() < 1e-4 && (d50[1] - 0.35850).abs() < 1e-4,
            "{d50:?}"
        );
        assert!(daylight_xy(3000.0).is_err());
        assert!(temperature_xy(f64::NAN).is_err());
        assert!(temperature_xy(500.0).is_err());
        assert_eq!(
            temperature_xy(3000.0).unwrap(),
            planckian_xy(3000.0).unwrap()
        );
        assert_eq!(
            temperature_xy(4000.0).unwrap(),
            daylight_xy(4000.0).unwrap()
        );
    }

    #[test]
    fn cct_inverts_the_loci() {
        // Robertson's method is good to a few kelvin on the Planckian locus.
        for t in [2000.0, 2856.0, 3500.0, 4500.0, 6500.0, 9000.0] {
            let got = cct(planckian_xy(t).unwrap()).unwrap();
            assert!((got - t).abs() < 0.002 * t, "{t}: {got}");
        }
        // Daylight sits above the locus; its CCT is its nominal temperature to within ~0.5 %.
        let d65 = cct(daylight_xy(6504.0).unwrap()).unwrap();
        assert!((d65 - 6504.0).abs() < 30.0, "{d65}");
        let d50 = cct(D50_XY).unwrap();
        assert!((d50 - 5003.0).abs() < 20.0, "{d50}");
        assert!(cct([0.5, 0.6]).is_err());
        assert!(cct([f64::NAN, 0.3]).is_err());
    }

    #[test]
    fn weight_is_linear_in_inverse_temperature_and_clamped() {
        let (t1, t2) = (2856.0, 6504.0);
        assert_eq!(dng_weight(2000.0, t1, t2), 1.0);
        assert_eq!(dng_weight(9000.0, t1, t2), 0.0);
        assert!((dng_weight(t1, t1, t2) - 1.0).abs() < 1e-12);
        let mid = 2.0 / (1.0 / t1 + 1.0 / t2);
        assert!((dng_weight(mid, t1, t2) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn neutral_iteration_finds_a_linear_cameras_light() {
        // A camera that is a fixed matrix: the neutral of a light is M·XYZ; the iteration must
        // give that light's chromaticity back whatever the weight.
        let m: Mat3 = [[0.7, 0.3, -0.05], [0.2, 0.9, -0.1], [0.0, 0.1, 0.6]];
        let inv = super::super::spaces::invert(&m);
        for t in [3000.0, 4300.0, 6000.0] {
            let xy = temperature_xy(t).unwrap();
            let n = super::super::spaces::apply(&m, xy_to_xyz(xy));
            let got = neutral_to_xy(n, [2856.0, 6504.0], |c, _| {
                Some(super::super::spaces::apply(&inv, c))
            })
            .unwrap();
            assert!((got[0] - xy[0]).abs() < 1e-9 && (got[1] - xy[1]).abs() < 1e-9);
        }
        assert!(neutral_to_xy([0.0, 1.0, 1.0], [2856.0, 6504.0], |c, _| Some(c)).is_err());
    }
}
