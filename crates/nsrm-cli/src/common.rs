//! Options shared by several subcommands: where the training data comes from.

use anyhow::{Context, Result};
use clap::Args as ClapArgs;
use nsrm::Kind;
use nsrm::{parse_white, TrainingSet};
use nsrm::{simulate, Camera, Grid, Illuminant, Reflectances};
use nsrm_io::{Concern, Param};
use std::path::PathBuf;

/// An error in how the command was called (exit status 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct UsageError(pub String);

/// Where training patches come from: simulated from spectra, or measured (`--training`).
#[derive(Debug, Clone, ClapArgs)]
pub(crate) struct TrainingArgs {
    /// Camera sensitivities: a built-in name (nikon-d5100) or a CSV file (wavelength, R, G, B).
    #[arg(
        help_heading = "Training data",
        long,
        default_value = "nikon-d5100",
        value_name = "NAME|FILE"
    )]
    pub(crate) camera: String,
    /// Reflectances, one column per patch: a built-in name (rawtoaces-190, cc24) or a CSV file,
    /// e.g. a ColorChecker SG (columns A1..N10).
    #[arg(
        help_heading = "Training data",
        long,
        default_value = "rawtoaces-190",
        value_name = "NAME|FILE"
    )]
    pub(crate) reflectances: String,
    /// Which patches to use: `all`, a list of labels (A1,C3,…), or a rectangle of chart labels
    /// such as B2:M9 (columns B..M × rows 2..9: the SG's inner 96).
    #[arg(
        help_heading = "Training data",
        long,
        default_value = "all",
        value_name = "SPEC"
    )]
    pub(crate) patches: String,
    /// Wavelength grid for the Riemann sums, START:END:STEP in nm.
    #[arg(
        help_heading = "Training data",
        long,
        default_value = "400:700:10",
        value_name = "START:END:STEP"
    )]
    pub(crate) grid: String,
    /// Measured patches instead of spectra: a CSV `label,R,G,B,X,Y,Z` or `label,R,G,B,L,a,b`,
    /// with a `# white: X,Y,Z` line before the header naming the white the values are relative
    /// to (`chart extract` writes it), or else `--white`.
    #[arg(help_heading = "Training data", long, value_name = "FILE", conflicts_with_all = ["camera", "reflectances", "grid"])]
    pub(crate) training: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) white: WhiteArg,
}

/// `--white`: the white a `--training` file's values are relative to.
#[derive(Debug, Clone, ClapArgs)]
pub(crate) struct WhiteArg {
    /// The white of a `--training` file's X,Y,Z or L,a,b, when the file has no `# white:` line
    /// (if it has one, they must agree): `X,Y,Z`, a chromaticity `x,y` (at Y = 100), `D50`, or
    /// an illuminant name or file (its perfect white, Y = 100). There is no default.
    #[arg(long, value_name = "WHITE", requires = "training")]
    pub(crate) white: Option<String>,
}

impl WhiteArg {
    /// The parsed white, if given.
    pub(crate) fn get(&self) -> Result<Option<[f64; 3]>> {
        self.white
            .as_deref()
            .map(parse_white)
            .transpose()
            .context("--white")
    }
}

impl TrainingArgs {
    /// The files these options read (for `illuminant`), for the run's output session: the
    /// measured CSV, or the spectra given as files (built-in names are no files).
    pub(crate) fn input_files<'a>(&'a self, illuminant: &'a str) -> Vec<&'a std::path::Path> {
        match &self.training {
            Some(p) => vec![p.as_path()],
            None => [self.camera.as_str(), self.reflectances.as_str(), illuminant]
                .into_iter()
                .filter_map(super::outputs::file_arg)
                .collect(),
        }
    }

    /// Builds the training set for `illuminant` (ignored with `--training`).
    pub(crate) fn load(&self, illuminant: &str) -> Result<TrainingSet> {
        let data = match &self.training {
            Some(path) => read_measured(path, self.white.get()?)?,
            None => {
                let grid = Grid::parse(&self.grid)?;
                let camera = Camera::from_name_or_path(&self.camera).context("--camera")?;
                let ill = Illuminant::from_name_or_path(illuminant).context("--illuminant")?;
                let refl = Reflectances::from_name_or_path(&self.reflectances)
                    .context("--reflectances")?;
                simulate(&camera, &ill, &refl, &grid)
                    .with_context(|| format!("simulating the camera under {illuminant}"))?
            }
        };
        Ok(data.select(&self.patches)?)
    }
}

/// `--training FILE`: the measured patches; a file that names no white asks for `--white`.
pub(crate) fn read_measured(
    path: &std::path::Path,
    white: Option<[f64; 3]>,
) -> Result<TrainingSet> {
    use nsrm::TrainingError as E;
    TrainingSet::read_measured(path, white).map_err(|e| match e {
        e @ E::NeedsWhite { .. } => anyhow::Error::new(e).context(
            "--training needs --white X,Y,Z|x,y|D50|ILLUMINANT (the file has no `# white:` line)",
        ),
        e @ E::WhiteConflict { .. } => anyhow::Error::new(e).context("--white"),
        e => e.into(),
    })
}

/// Parses `lrm,prm,rprm,nsrm`.
pub(crate) fn parse_models(spec: &str) -> Result<Vec<Kind>> {
    let mut v = Vec::new();
    for s in spec.split(',').filter(|s| !s.trim().is_empty()) {
        let k = Kind::parse(s)?;
        if !v.contains(&k) {
            v.push(k);
        }
    }
    if v.is_empty() {
        return Err(UsageError("--kinds names no model kind".into()).into());
    }
    Ok(v)
}

/// Parses `--orders` (or `--order`, named by `flag` in messages): `3`, `1-4` or `1,3`.
pub(crate) fn parse_orders(spec: &str, flag: &str) -> Result<Vec<u8>> {
    let bad = || {
        UsageError(if flag == "--order" {
            format!("--order `{spec}`: expected a whole number within 1..4")
        } else {
            format!("{flag} `{spec}`: expected N, A-B or a list, within 1..4")
        })
    };
    let mut v = Vec::new();
    for part in spec.split(',') {
        let part = part.trim();
        let (a, b) = match part.split_once('-') {
            Some((a, b)) => (a.trim(), b.trim()),
            None => (part, part),
        };
        let a: u8 = a.parse().map_err(|_| bad())?;
        let b: u8 = b.parse().map_err(|_| bad())?;
        if a < 1 || b > 4 || a > b {
            return Err(bad().into());
        }
        for o in a..=b {
            if !v.contains(&o) {
                v.push(o);
            }
        }
    }
    Ok(v)
}

/// The flag that sets each library parameter: the one place the binary spells them.
pub(crate) fn flag(p: Param) -> &'static str {
    match p {
        Param::MaxPixels => "--max-pixels",
        Param::Layer => "--layer",
        Param::Exposure => "--exposure",
        Param::Noise => "--noise",
        Param::PatchSize => "--patch-size",
        Param::Gap => "--gap",
        Param::Columns => "--columns",
        Param::Corners => "--corners",
        Param::Flat => "--flat",
        Param::ReferenceWhite => "--reference-white",
        Param::Reflectances => "--reflectances",
        Param::WhiteLevel => "--white-level",
        Param::WhitePatch => "--white-patch",
    }
}

/// What to do about a failure that `p`'s flag is the way out of.
fn remedy(p: Param) -> String {
    let f = flag(p);
    match p {
        Param::MaxPixels => format!("raise the limit with {f} N if the frame is genuine"),
        Param::Layer => format!("pick the layer with {f} NAME"),
        Param::Corners => format!(
            "give the chart's corners with {f} \"X,Y X,Y X,Y X,Y\" (first patch's corner first, \
             then clockwise)"
        ),
        Param::ReferenceWhite => format!("pass {f} X,Y,Z or an illuminant (D50 for X-Rite tables)"),
        Param::Reflectances => format!("pass {f} FILE"),
        Param::WhitePatch => format!("name a neutral patch with {f} LABEL"),
        _ => format!("see {f}"),
    }
}

/// An error as the binary reports it: the whole context chain, with the flag whose value is at
/// fault in front (`--corners: …`), and a hint naming the flag that is the way out, if any.
pub(crate) fn explain(e: &anyhow::Error) -> (String, Option<String>) {
    let concern = e.chain().find_map(super::errors::concern);
    match concern {
        Some(Concern::Value(p)) => (format!("{}: {e:#}", flag(p)), None),
        Some(Concern::Remedy(p)) => (format!("{e:#}"), Some(remedy(p))),
        None => (format!("{e:#}"), None),
    }
}

/// An error's message and its causes joined by `: ` (what `{:#}` prints of it as an `anyhow`
/// error).
pub(crate) fn error_chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text.push_str(": ");
        text.push_str(&c.to_string());
        cause = c.source();
    }
    text
}

/// [`explain`] on one line, of an error held by reference (a batch executor's per-frame
/// failures): the flag at fault in front, or the hint after `(hint: …)`.
pub(crate) fn explain_line(e: &(dyn std::error::Error + 'static)) -> String {
    let concern = std::iter::successors(Some(e), |e| e.source()).find_map(super::errors::concern);
    let text = error_chain(e);
    match concern {
        Some(Concern::Value(p)) => format!("{}: {text}", flag(p)),
        Some(Concern::Remedy(p)) => format!("{text} (hint: {})", remedy(p)),
        None => text,
    }
}
