//! Spectral data and the synthetic camera.
//!
//! Reads spectral CSV tables (first column wavelength in nm, then one named column per spectrum),
//! resamples them onto a wavelength [`Grid`] by linear interpolation (zero outside a table's range),
//! and integrates camera RGB and CIE XYZ with a Riemann sum ([`simulate`]).
//!
//! Scales (see [`simulate`]): XYZ so that the perfect white under the illuminant has `Y = 100`;
//! camera RGB so that the perfect white has `G = 1`, channel ratios kept (raw, not white-balanced).

mod builtin;
mod computed;
mod csv;
#[cfg(test)]
mod fuzz_tests;

pub(crate) use builtin::{
    builtin_camera, builtin_illuminant, builtin_reflectances, cie1931_cmf, CAMERAS, ILLUMINANTS,
    REFLECTANCES,
};
pub(crate) use csv::parse_csv;

use crate::training_set::{Provenance, TrainingSet};
use std::path::Path;

/// Errors from reading spectral data or simulating a camera.
#[derive(Debug, thiserror::Error)]
pub enum SpectralError {
    /// A spectral CSV could not be read.
    #[error("{source_name}: cannot read: {err}")]
    Io {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
        /// The I/O error.
        err: std::io::Error,
    },
    /// A spectral CSV is empty.
    #[error(
        "{source_name}: the file is empty (expected a header `wavelength_nm,NAME,...` and rows)"
    )]
    Empty {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
    },
    /// A spectral CSV's header has only the wavelength column.
    #[error("{source_name}: the header has no spectrum columns after the wavelength column")]
    NoColumns {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
    },
    /// A malformed CSV: a ragged row, a cell that is not a finite number.
    #[error(transparent)]
    Csv(#[from] crate::csv_table::CsvError),
    /// The wavelengths of a spectral CSV do not strictly increase.
    #[error("{source_name}: line {line}: wavelength {wavelength} nm does not increase (previous {previous} nm)")]
    NonIncreasing {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
        /// The line number of the offending row.
        line: usize,
        /// The wavelength on that line, in nm.
        wavelength: f64,
        /// The wavelength of the row before, in nm.
        previous: f64,
    },
    /// A spectral CSV has a header but no data rows.
    #[error("{source_name}: has no data rows")]
    NoRows {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
    },
    /// Two spectrum columns of a CSV have the same name.
    #[error("{source_name}: duplicate column name `{column}`")]
    DuplicateColumn {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
        /// The repeated column name.
        column: String,
    },
    /// A camera sensitivity file without exactly 3 spectrum columns.
    #[error(
        "{source_name}: a camera file needs exactly 3 spectrum columns (R, G, B), found {found}"
    )]
    CameraColumns {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
        /// The number of spectrum columns found.
        found: usize,
    },
    /// An illuminant file without exactly 1 spectrum column.
    #[error("{source_name}: an illuminant file needs exactly 1 spectrum column, found {found}")]
    IlluminantColumns {
        /// The file, or built-in name, the spectra came from.
        source_name: String,
        /// The number of spectrum columns found.
        found: usize,
    },
    /// A malformed wavelength grid (`START:END:STEP`).
    #[error("invalid grid `{spec}`: {why} (expected START:END:STEP in nm, e.g. 400:700:10)")]
    Grid {
        /// The grid as given.
        spec: String,
        /// What is wrong with it.
        why: String,
    },
    /// The perfect white integrates to zero (or a non-finite value) on the grid.
    #[error("{what}: the perfect white integrates to {value} (no overlap between the spectra and the grid?)")]
    DegenerateWhite {
        /// The spectra and channel integrated (e.g. an illuminant's Y).
        what: String,
        /// The integral found.
        value: f64,
    },
    /// Simulated values that overflow once the camera's white green is scaled to 1 (a camera
    /// file whose channels are far larger than its green).
    #[error("camera {camera}: patch `{patch}` under {illuminant} has RGB {rgb:?} once the white's green is 1 (values too large for their green?)")]
    Overflow {
        /// The camera's source (its file).
        camera: String,
        /// The illuminant's source.
        illuminant: String,
        /// The first patch that overflows.
        patch: String,
        /// Its RGB.
        rgb: [f64; 3],
    },
    /// A name that looks like a file path (a directory part or a file extension), and no such
    /// file exists.
    #[error("{path}: no such file (a {what} CSV was expected there)")]
    MissingFile {
        /// The kind of spectrum expected (camera, illuminant, ...).
        what: &'static str,
        /// The path given.
        path: String,
    },
    /// A name that is neither a built-in spectrum nor an existing file.
    #[error("unknown {what} `{name}` (built-in: {known}); to read a file, give a path to an existing CSV")]
    UnknownName {
        /// The kind of spectrum asked for (camera, illuminant, ...).
        what: &'static str,
        /// The name given.
        name: String,
        /// The built-in names of that kind, comma-separated.
        known: String,
    },
}

impl SpectralError {
    /// True for a malformed wavelength grid.
    pub fn is_usage(&self) -> bool {
        matches!(self, SpectralError::Grid { .. })
    }
}

/// A wavelength grid, `start..=end` in steps of `step` nm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// The first wavelength, nm.
    pub start: f64,
    /// The last wavelength, nm (included when on the grid).
    pub end: f64,
    /// The spacing, nm.
    pub step: f64,
}

impl Default for Grid {
    /// The paper's grid: 400–700 nm in 10 nm steps.
    fn default() -> Self {
        Grid {
            start: 400.0,
            end: 700.0,
            step: 10.0,
        }
    }
}

impl Grid {
    /// Parses `START:END:STEP` (nm).
    pub fn parse(spec: &str) -> Result<Grid, SpectralError> {
        let err = |why: &str| SpectralError::Grid {
            spec: spec.to_string(),
            why: why.to_string(),
        };
        let parts: Vec<&str> = spec.split(':').collect();
        if parts.len() != 3 {
            return Err(err("three numbers separated by `:` are needed"));
        }
        let mut v = [0.0; 3];
        for (slot, p) in v.iter_mut().zip(&parts) {
            *slot = p
                .trim()
                .parse::<f64>()
                .map_err(|_| err(&format!("`{p}` is not a number")))?;
            if !slot.is_finite() {
                return Err(err("values must be finite"));
            }
        }
        let g = Grid {
            start: v[0],
            end: v[1],
            step: v[2],
        };
        if g.step <= 0.0 {
            return Err(err("STEP must be positive"));
        }
        if g.end < g.start {
            return Err(err("END must not be below START"));
        }
        // Counted in f64 before any integer conversion: `0:1e300:1e-300` is refused, not
        // overflowed.
        let n = ((g.end - g.start) / g.step + 1e-9).floor();
        if !(n.is_finite() && n < 100_000.0) {
            return Err(err("more than 100000 samples (the limit)"));
        }
        Ok(g)
    }

    /// Number of samples.
    pub(crate) fn len(&self) -> usize {
        // `as` saturates (NaN → 0); the addition must too for hand-made grids.
        (((self.end - self.start) / self.step + 1e-9).floor() as usize).saturating_add(1)
    }

    /// The sample wavelengths.
    pub(crate) fn wavelengths(&self) -> Vec<f64> {
        (0..self.len())
            .map(|i| self.start + i as f64 * self.step)
            .collect()
    }
}

impl std::fmt::Display for Grid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.start, self.end, self.step)
    }
}

/// A table of spectra sampled at common wavelengths.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SpectralTable {
    /// Where it came from (a file path or `builtin:NAME`), for messages and provenance.
    pub source_name: String,
    /// Strictly increasing wavelengths in nm.
    pub wavelengths: Vec<f64>,
    /// Column names, one per spectrum.
    pub names: Vec<String>,
    /// `values[j][i]`: spectrum `j` at `wavelengths[i]`.
    pub values: Vec<Vec<f64>>,
}

impl SpectralTable {
    /// Reads a CSV file.
    pub(crate) fn read(path: &Path) -> Result<SpectralTable, SpectralError> {
        let source_name = path.display().to_string();
        let text = crate::limits::read_text(path).map_err(|err| SpectralError::Io {
            source_name: source_name.clone(),
            err,
        })?;
        parse_csv(&text, &source_name)
    }

    /// Linear interpolation of spectrum `j` at wavelength `w`; zero outside the table's range.
    pub(crate) fn value_at(&self, j: usize, w: f64) -> f64 {
        let wl = &self.wavelengths;
        let v = &self.values[j];
        let n = wl.len();
        if n == 0 || w < wl[0] || w > wl[n - 1] {
            return 0.0;
        }
        // First index with wl[i] >= w.
        let i = wl.partition_point(|&x| x < w);
        if wl[i] == w {
            return v[i];
        }
        let (w0, w1) = (wl[i - 1], wl[i]);
        let t = (w - w0) / (w1 - w0);
        v[i - 1] + t * (v[i] - v[i - 1])
    }

    /// Every spectrum resampled onto `grid`.
    pub(crate) fn resample(&self, grid: &Grid) -> Vec<Vec<f64>> {
        let ws = grid.wavelengths();
        (0..self.names.len())
            .map(|j| ws.iter().map(|&w| self.value_at(j, w)).collect())
            .collect()
    }
}

/// A camera: three spectral sensitivities (R, G, B), in that column order.
#[derive(Debug, Clone)]
pub struct Camera(pub(crate) SpectralTable);

impl Camera {
    /// Where the sensitivities came from: a file path or `builtin:NAME`.
    pub fn source_name(&self) -> &str {
        &self.0.source_name
    }

    pub(crate) fn new(table: SpectralTable) -> Result<Camera, SpectralError> {
        if table.names.len() != 3 {
            return Err(SpectralError::CameraColumns {
                source_name: table.source_name,
                found: table.names.len(),
            });
        }
        Ok(Camera(table))
    }

    /// A built-in name (`nikon-d5100`) or a path to a CSV file.
    pub fn from_name_or_path(spec: &str) -> Result<Camera, SpectralError> {
        let table = match builtin_camera(spec) {
            Some(t) => t,
            None => table_from_path(spec, "camera", CAMERAS)?,
        };
        Camera::new(table)
    }
}

/// An illuminant: one spectral power distribution.
#[derive(Debug, Clone)]
pub struct Illuminant(pub(crate) SpectralTable);

impl Illuminant {
    /// Where the spectrum came from: a file path or `builtin:NAME`.
    pub fn source_name(&self) -> &str {
        &self.0.source_name
    }

    pub(crate) fn new(table: SpectralTable) -> Result<Illuminant, SpectralError> {
        if table.names.len() != 1 {
            return Err(SpectralError::IlluminantColumns {
                source_name: table.source_name,
                found: table.names.len(),
            });
        }
        Ok(Illuminant(table))
    }

    /// A built-in name (`D65`, `FL3.15`, `FL7`, `TL865`, `LED-B5`, `LED-YAG`) or a CSV path.
    pub fn from_name_or_path(spec: &str) -> Result<Illuminant, SpectralError> {
        let table = match builtin_illuminant(spec).or_else(|| computed::computed_illuminant(spec)) {
            Some(t) => t,
            None => table_from_path(spec, "illuminant", ILLUMINANTS).map_err(|e| match e {
                SpectralError::UnknownName { what, name, known } => SpectralError::UnknownName {
                    what,
                    name,
                    known: format!("{known}; computed: {}", computed::NAMES_AND_RANGES.as_str()),
                },
                e => e,
            })?,
        };
        Illuminant::new(table)
    }

    /// Whether `spec` is a built-in or computed name (never a file).
    pub fn is_builtin(spec: &str) -> bool {
        builtin_illuminant(spec).is_some() || computed::computed_illuminant(spec).is_some()
    }
}

/// Reflectances, one spectrum per patch (column names are the patch labels).
#[derive(Debug, Clone)]
pub struct Reflectances(pub(crate) SpectralTable);

impl Reflectances {
    /// A perfect white: reflectance 1 at every wavelength (300–900 nm).
    pub fn perfect_white() -> Reflectances {
        let table = csv::parse_csv("wavelength_nm,white\n300,1\n900,1\n", "perfect white")
            .expect("a well-formed built-in table");
        Reflectances(table)
    }

    /// Where the spectra came from: a file path or `builtin:NAME`.
    pub fn source_name(&self) -> &str {
        &self.0.source_name
    }

    /// A built-in name (`rawtoaces-190`, `cc24`) or a CSV path.
    pub fn from_name_or_path(spec: &str) -> Result<Reflectances, SpectralError> {
        let table = match builtin_reflectances(spec) {
            Some(t) => t,
            None => table_from_path(spec, "reflectance set", REFLECTANCES)?,
        };
        Ok(Reflectances(table))
    }
}

/// The name shown for a table: `D65` for `builtin:D65`, the file stem for a path.
pub fn display_name(source_name: &str) -> String {
    if let Some(n) = source_name.strip_prefix("builtin:") {
        return n.to_string();
    }
    Path::new(source_name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| source_name.to_string())
}

fn table_from_path(
    spec: &str,
    what: &'static str,
    known: &[(&str, &str)],
) -> Result<SpectralTable, SpectralError> {
    let path = Path::new(spec);
    if !path.exists() && looks_like_a_path(spec) {
        return Err(SpectralError::MissingFile {
            what,
            path: spec.to_string(),
        });
    }
    if !path.exists() {
        return Err(SpectralError::UnknownName {
            what,
            name: spec.to_string(),
            known: known.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", "),
        });
    }
    SpectralTable::read(path)
}

/// A spec that names a file rather than a built-in: it has a directory part or ends in a file
/// extension that no built-in name has (`.csv`, `.txt`, `.tsv`).
fn looks_like_a_path(spec: &str) -> bool {
    let lower = spec.to_ascii_lowercase();
    spec.contains('/')
        || spec.contains(std::path::MAIN_SEPARATOR)
        || [".csv", ".txt", ".tsv"].iter().any(|e| lower.ends_with(e))
}

/// XYZ of the perfect white (ρ = 1) under `illuminant` on `grid`, scaled to `Y = 100`.
pub fn white_xyz(illuminant: &Illuminant, grid: &Grid) -> Result<[f64; 3], SpectralError> {
    let cmf = cie1931_cmf().resample(grid);
    let e = illuminant.0.resample(grid).remove(0);
    let ones = vec![1.0; grid.len()];
    let y = riemann(&e, &ones, &cmf[1], grid.step);
    if !(y > 0.0 && y.is_finite()) {
        return Err(SpectralError::DegenerateWhite {
            what: format!("illuminant {} (Y)", illuminant.0.source_name),
            value: y,
        });
    }
    Ok([
        100.0 * riemann(&e, &ones, &cmf[0], grid.step) / y,
        100.0,
        100.0 * riemann(&e, &ones, &cmf[2], grid.step) / y,
    ])
}

fn riemann(a: &[f64], b: &[f64], c: &[f64], step: f64) -> f64 {
    a.iter()
        .zip(b)
        .zip(c)
        .map(|((x, y), z)| x * y * z)
        .sum::<f64>()
        * step
}

/// [`simulate`] with the camera, illuminant and reflectances given as built-in names or CSV paths
/// (as on the command line), e.g. `simulate_named("nikon-d5100", "D65", "rawtoaces-190", &grid)`.
pub fn simulate_named(
    camera: &str,
    illuminant: &str,
    reflectances: &str,
    grid: &Grid,
) -> Result<TrainingSet, SpectralError> {
    simulate(
        &Camera::from_name_or_path(camera)?,
        &Illuminant::from_name_or_path(illuminant)?,
        &Reflectances::from_name_or_path(reflectances)?,
        grid,
    )
}

/// Simulates camera RGB and CIE 1931 2° XYZ for each reflectance under `illuminant`.
///
/// `XYZ_k = Σ_λ E(λ) ρ(λ) x̄_k(λ) Δλ`, scaled so the perfect white (ρ = 1) has `Y = 100`.
/// `RGB_k = Σ_λ E(λ) ρ(λ) c_k(λ) Δλ`, scaled so the perfect white has `G = 1` (one factor for all
/// three channels: the camera's raw channel ratios are kept).
pub fn simulate(
    camera: &Camera,
    illuminant: &Illuminant,
    reflectances: &Reflectances,
    grid: &Grid,
) -> Result<TrainingSet, SpectralError> {
    let cmf = cie1931_cmf().resample(grid);
    let cam = camera.0.resample(grid);
    let e = illuminant.0.resample(grid).remove(0);
    let refl = reflectances.0.resample(grid);
    let ones = vec![1.0; grid.len()];

    let white_xyz = white_xyz(illuminant, grid)?;
    let y_white = riemann(&e, &ones, &cmf[1], grid.step);
    let g_white = riemann(&e, &ones, &cam[1], grid.step);
    if !(g_white > 0.0 && g_white.is_finite()) {
        return Err(SpectralError::DegenerateWhite {
            what: format!(
                "camera {} green under {}",
                camera.0.source_name, illuminant.0.source_name
            ),
            value: g_white,
        });
    }
    let kx = 100.0 / y_white;
    let kc = 1.0 / g_white;
    let white_rgb = [
        kc * riemann(&e, &ones, &cam[0], grid.step),
        1.0,
        kc * riemann(&e, &ones, &cam[2], grid.step),
    ];
    let mut rgb = Vec::with_capacity(refl.len());
    let mut xyz = Vec::with_capacity(refl.len());
    for r in &refl {
        rgb.push([
            kc * riemann(&e, r, &cam[0], grid.step),
            kc * riemann(&e, r, &cam[1], grid.step),
            kc * riemann(&e, r, &cam[2], grid.step),
        ]);
        xyz.push([
            kx * riemann(&e, r, &cmf[0], grid.step),
            kx * riemann(&e, r, &cmf[1], grid.step),
            kx * riemann(&e, r, &cmf[2], grid.step),
        ]);
    }
    let finite = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    let bad = (!finite(&white_rgb))
        .then(|| ("the perfect white".to_string(), white_rgb))
        .or_else(|| {
            let i = rgb.iter().position(|v| !finite(v))?;
            Some((
                reflectances.0.names.get(i).cloned().unwrap_or_default(),
                rgb[i],
            ))
        });
    if let Some((patch, rgb)) = bad {
        return Err(SpectralError::Overflow {
            camera: camera.0.source_name.clone(),
            illuminant: illuminant.0.source_name.clone(),
            patch,
            rgb,
        });
    }
    Ok(TrainingSet {
        labels: reflectances.0.names.clone(),
        rgb,
        xyz,
        white_xyz,
        white_rgb: Some(white_rgb),
        provenance: Provenance {
            source: "spectral".into(),
            camera: Some(camera.0.source_name.clone()),
            illuminant: Some(illuminant.0.source_name.clone()),
            reflectances: Some(reflectances.0.source_name.clone()),
            grid: Some(grid.to_string()),
            patches: None,
            capture: None,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_parse_and_len() {
        let g = Grid::parse("400:700:10").unwrap();
        assert_eq!(g.len(), 31);
        assert_eq!(g.wavelengths()[30], 700.0);
        assert!(Grid::parse("400:700").is_err());
        assert!(Grid::parse("400:700:0").is_err());
        assert!(Grid::parse("700:400:10").is_err());
        assert!(Grid::parse("a:700:10").is_err());
        assert_eq!(Grid::parse("380:780:5").unwrap().len(), 81);
    }

    #[test]
    fn interpolation_and_zero_outside() {
        let t = parse_csv("nm,a\n400,1\n410,3\n", "t").unwrap();
        assert_eq!(t.value_at(0, 400.0), 1.0);
        assert_eq!(t.value_at(0, 405.0), 2.0);
        assert_eq!(t.value_at(0, 410.0), 3.0);
        assert_eq!(t.value_at(0, 399.0), 0.0);
        assert_eq!(t.value_at(0, 411.0), 0.0);
    }

    #[test]
    fn white_scaling() {
        let cam = Camera::from_name_or_path("nikon-d5100").unwrap();
        let ill = Illuminant::from_name_or_path("D65").unwrap();
        let refl = Reflectances::from_name_or_path("cc24").unwrap();
        let ts = simulate(&cam, &ill, &refl, &Grid::default()).unwrap();
        // D65 white point, 2° observer, on a 10 nm grid: close to (95.04, 100, 108.88).
        assert!((ts.white_xyz[0] - 95.04).abs() < 0.3, "{:?}", ts.white_xyz);
        assert!((ts.white_xyz[2] - 108.88).abs() < 0.5, "{:?}", ts.white_xyz);
        assert_eq!(ts.labels.len(), 24);
        // Every patch is darker than the perfect white.
        for (rgb, xyz) in ts.rgb.iter().zip(&ts.xyz) {
            assert!(rgb[1] > 0.0 && rgb[1] < 1.0);
            assert!(xyz[1] > 0.0 && xyz[1] < 100.0);
        }
    }

    #[test]
    fn unknown_name_is_clear() {
        let e = Illuminant::from_name_or_path("D66")
            .unwrap_err()
            .to_string();
        assert!(e.contains("D65") && e.contains("D66"), "{e}");
        // A path that does not exist is a missing file, not an unknown name.
        for p in ["my_patches.csv", "data/sg.CSV", "./x"] {
            let e = Reflectances::from_name_or_path(p).unwrap_err();
            assert!(matches!(e, SpectralError::MissingFile { .. }), "{p}: {e}");
            let e = e.to_string();
            assert!(e.contains("no such file") && !e.contains("unknown"), "{e}");
        }
    }
}
