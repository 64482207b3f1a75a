//! Output colour spaces: 3×3 matrices from CIE XYZ to linear RGB spaces, with Bradford chromatic
//! adaptation from the scene's white to the space's white where they differ.

/// A 3×3 matrix, row-major: `out[i] = Σ_j m[i][j] · in[j]`.
pub type Mat3 = [[f64; 3]; 3];

/// Where corrected pixels are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum OutputSpace {
    /// CIE XYZ as the model produces it (relative to the training illuminant's white).
    #[cfg_attr(feature = "clap", value(name = "xyz"))]
    Xyz,
    /// Linear sRGB / Rec. 709 primaries, D65 white.
    #[cfg_attr(feature = "clap", value(name = "linear-srgb"))]
    LinearSrgb,
    /// ACEScg (AP1 primaries, ACES white ≈ D60).
    #[cfg_attr(feature = "clap", value(name = "acescg"))]
    Acescg,
    /// ACES2065-1 (AP0 primaries, ACES white ≈ D60).
    #[cfg_attr(feature = "clap", value(name = "aces2065-1"))]
    Aces2065_1,
}

impl OutputSpace {
    /// Every space with its command-line name.
    pub const ALL: [(OutputSpace, &'static str); 4] = [
        (OutputSpace::Xyz, "xyz"),
        (OutputSpace::LinearSrgb, "linear-srgb"),
        (OutputSpace::Acescg, "acescg"),
        (OutputSpace::Aces2065_1, "aces2065-1"),
    ];

    /// Parses a command-line name (`xyz`, `linear-srgb`, `acescg`, `aces2065-1`).
    pub fn parse(name: &str) -> Option<OutputSpace> {
        Self::ALL
            .iter()
            .find(|(_, n)| n.eq_ignore_ascii_case(name))
            .map(|(s, _)| *s)
    }

    /// The command-line name.
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(s, _)| *s == self).unwrap().1
    }

    /// The ASWF colour-interop identifier of pixels in this space (`colorInteropID`).
    pub fn interop_id(self) -> &'static str {
        match self {
            OutputSpace::Xyz => "lin_ciexyzd65_scene",
            OutputSpace::LinearSrgb => "lin_rec709_scene",
            OutputSpace::Acescg => "lin_ap1_scene",
            OutputSpace::Aces2065_1 => "lin_ap0_scene",
        }
    }

    /// (primaries xy R, G, B, white xy) of an RGB space; `None` for XYZ.
    pub fn primaries(self) -> Option<([[f64; 2]; 3], [f64; 2])> {
        const D65: [f64; 2] = [0.3127, 0.3290];
        const ACES: [f64; 2] = [0.32168, 0.33767];
        match self {
            OutputSpace::Xyz => None,
            OutputSpace::LinearSrgb => Some(([[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]], D65)),
            OutputSpace::Acescg => Some(([[0.713, 0.293], [0.165, 0.830], [0.128, 0.044]], ACES)),
            OutputSpace::Aces2065_1 => {
                Some(([[0.7347, 0.2653], [0.0, 1.0], [0.0001, -0.0770]], ACES))
            }
        }
    }

    /// The matrix taking XYZ relative to `scene_white` (any scale) to this space, adapting the
    /// scene white to the space's white with Bradford.
    ///
    /// [`OutputSpace::Xyz`] is D65-referred XYZ (its interop ID says so): the identity when the scene
    /// white is D65 to within 1e-3 in xy (e.g. D65 integrated on a coarse grid),
    /// otherwise a Bradford adaptation from the scene white to D65.
    ///
    /// The shortcut is for a model's own training white only: a frame's white (a combination's,
    /// `apply --white`) adapts exactly ([`OutputSpace::from_xyz_exact`]), so that the output moves
    /// smoothly with the white.
    pub fn from_xyz(self, scene_white: [f64; 3]) -> [[f64; 3]; 3] {
        if self == OutputSpace::Xyz {
            let sum: f64 = scene_white.iter().sum();
            let xy = [scene_white[0] / sum, scene_white[1] / sum];
            let d = (xy[0] - D65_XY[0]).hypot(xy[1] - D65_XY[1]);
            if d <= D65_XY_TOLERANCE {
                return IDENTITY;
            }
        }
        self.from_xyz_exact(scene_white)
    }

    /// [`OutputSpace::from_xyz`] without the "counts as D65" shortcut: always the Bradford
    /// adaptation from the scene white to the space's white (D65 for XYZ).
    pub fn from_xyz_exact(self, scene_white: [f64; 3]) -> [[f64; 3]; 3] {
        match self.primaries() {
            None => {
                let sw = [
                    scene_white[0] / scene_white[1],
                    1.0,
                    scene_white[2] / scene_white[1],
                ];
                bradford(sw, xy_to_xyz(D65_XY))
            }
            Some((prim, white)) => {
                let to_xyz = rgb_to_xyz(prim, white);
                let from_xyz = invert(&to_xyz);
                let dst_white = xy_to_xyz(white);
                let sw = [
                    scene_white[0] / scene_white[1],
                    1.0,
                    scene_white[2] / scene_white[1],
                ];
                mul(&from_xyz, &bradford(sw, dst_white))
            }
        }
    }
}

/// CIE D65 chromaticity (2° observer).
pub(crate) const D65_XY: [f64; 2] = [0.3127, 0.3290];

/// How far (xy distance) a model's training white may be from D65 and still count as D65 for XYZ
/// output (a frame's white never does: [`OutputSpace::from_xyz_exact`]).
pub(crate) const D65_XY_TOLERANCE: f64 = 1e-3;

/// The identity matrix.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// xy chromaticity → XYZ with Y = 1.
pub fn xy_to_xyz(xy: [f64; 2]) -> [f64; 3] {
    [xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1]]
}

/// The normalised primary matrix (RGB → XYZ, white maps to Y = 1).
pub fn rgb_to_xyz(prim: [[f64; 2]; 3], white: [f64; 2]) -> Mat3 {
    let cols: Vec<[f64; 3]> = prim.iter().map(|p| xy_to_xyz(*p)).collect();
    let p = [
        [cols[0][0], cols[1][0], cols[2][0]],
        [cols[0][1], cols[1][1], cols[2][1]],
        [cols[0][2], cols[1][2], cols[2][2]],
    ];
    let s = apply(&invert(&p), xy_to_xyz(white));
    let mut m = p;
    for row in m.iter_mut() {
        for (v, sj) in row.iter_mut().zip(s) {
            *v *= sj;
        }
    }
    m
}

/// Bradford chromatic adaptation from white `src` to white `dst` (both XYZ).
pub(crate) fn bradford(src: [f64; 3], dst: [f64; 3]) -> Mat3 {
    const B: Mat3 = [
        [0.8951, 0.2664, -0.1614],
        [-0.7502, 1.7135, 0.0367],
        [0.0389, -0.0685, 1.0296],
    ];
    let s = apply(&B, src);
    let d = apply(&B, dst);
    let diag = [
        [d[0] / s[0], 0.0, 0.0],
        [0.0, d[1] / s[1], 0.0],
        [0.0, 0.0, d[2] / s[2]],
    ];
    mul(&invert(&B), &mul(&diag, &B))
}

/// `m · v`.
pub fn apply(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// `a · b`.
pub fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// The inverse of a 3×3 matrix (nalgebra's), or `None` when it is singular or too close to
/// singular to be worth inverting: a non-finite entry, or `|det|` at most `1e-12` of the product
/// of its row norms (Hadamard's bound on `|det|`, so the test does not depend on the scale).
pub fn try_invert(m: &Mat3) -> Option<Mat3> {
    let a = nalgebra::Matrix3::from_fn(|i, j| m[i][j]);
    let hadamard: f64 = m
        .iter()
        .map(|r| r.iter().map(|v| v * v).sum::<f64>().sqrt())
        .product();
    let det = a.determinant();
    if !(hadamard.is_finite() && det.is_finite() && det.abs() > 1e-12 * hadamard) {
        return None;
    }
    let inv = a.try_inverse()?;
    let out: Mat3 = [0, 1, 2].map(|i| [0, 1, 2].map(|j| inv[(i, j)]));
    out.iter().flatten().all(|v| v.is_finite()).then_some(out)
}

/// [`try_invert`] for the matrices that are invertible by construction (primaries, Bradford, the
/// output matrices of a checked white): should one be singular after all, every entry is NaN
/// (never a silently huge inverse), which the callers' finiteness checks refuse.
pub fn invert(m: &Mat3) -> Mat3 {
    try_invert(m).unwrap_or([[f64::NAN; 3]; 3])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_round_trips_and_singular_matrices_are_refused() {
        let m = [
            [0.8951, 0.2664, -0.1614],
            [-0.7502, 1.7135, 0.0367],
            [0.0389, -0.0685, 1.0296],
        ];
        let p = mul(&m, &try_invert(&m).unwrap());
        for (i, row) in p.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14, "{p:?}");
            }
        }
        // Scale does not matter, singularity does.
        assert!(try_invert(&m.map(|r| r.map(|v| v * 1e-30))).is_some());
        let singular = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]];
        assert!(try_invert(&singular).is_none());
        let nearly = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0 + 1e-14], [0.0, 1.0, 1.0]];
        assert!(try_invert(&nearly).is_none());
        assert!(try_invert(&[[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_none());
        assert!(invert(&singular).iter().flatten().all(|v| v.is_nan()));
        assert!(try_invert(&[[0.0; 3]; 3]).is_none());
    }

    #[test]
    fn srgb_matrix_matches_iec_61966() {
        // XYZ (D65) → linear sRGB, IEC 61966-2-1 to 4 decimals.
        let m = OutputSpace::LinearSrgb.from_xyz(xy_to_xyz([0.3127, 0.3290]));
        let want = [
            [3.2406, -1.5372, -0.4986],
            [-0.9689, 1.8758, 0.0415],
            [0.0557, -0.2040, 1.0570],
        ];
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[i][j] - want[i][j]).abs() < 2e-3, "{m:?}");
            }
        }
    }

    #[test]
    fn scene_white_maps_to_equal_rgb() {
        for (space, _) in OutputSpace::ALL {
            if space == OutputSpace::Xyz {
                continue;
            }
            let w = [96.0, 100.0, 80.0];
            let rgb = apply(&space.from_xyz(w), [0.96, 1.0, 0.80]);
            for k in 0..3 {
                assert!((rgb[k] - 1.0).abs() < 1e-9, "{space:?}: {rgb:?}");
            }
        }
        // XYZ output is D65-referred: identity for a D65 white, Bradford to D65 otherwise.
        assert_eq!(OutputSpace::Xyz.from_xyz([95.04, 100.0, 108.88]), IDENTITY);
        let a = OutputSpace::Xyz.from_xyz([96.42, 100.0, 82.52]);
        let w = apply(&a, [0.9642, 1.0, 0.8252]);
        let d65 = xy_to_xyz(D65_XY);
        for k in 0..3 {
            assert!((w[k] - d65[k]).abs() < 1e-9, "{w:?}");
        }
    }

    #[test]
    fn ap0_matrix_matches_aces() {
        // ACES2065-1 RGB → XYZ from the ACES specification (S-2008-001), to 4 decimals.
        let (p, w) = OutputSpace::Aces2065_1.primaries().unwrap();
        let m = rgb_to_xyz(p, w);
        let want = [
            [0.9525524, 0.0, 0.0000937],
            [0.3439664, 0.7281661, -0.0721325],
            [0.0, 0.0, 1.0088252],
        ];
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[i][j] - want[i][j]).abs() < 1e-4, "{m:?}");
            }
        }
    }
}
