//! The studio's wire format. Requests are deserialised straight into the library's typed values
//! (the chart, the model kind, the objective, the ridge, the normalisation), each read by the
//! library's own parser: a request names them as the CLI's flags do (case-insensitively), and a
//! bad name is refused with the names allowed. Answers are these structs serialised, so that the
//! format the page reads is checked by the compiler.

use nsrm::{EvalResult, FitReport, Kind, Mat3, Normalise, Objective, Ridge, Stats};
use nsrm_chart::ChartKind;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::Value;

/// A value a request names in words, read by the library's parser (`Kind::parse`, …): the
/// names its CLI flag takes.
pub(crate) trait Named: Sized {
    /// The value `s` names, or a message that names the values allowed.
    fn parse_name(s: &str) -> Result<Self, String>;
    /// The name the CLI's flag takes for it.
    fn name_of(&self) -> String;
}

impl Named for Kind {
    fn parse_name(s: &str) -> Result<Kind, String> {
        Kind::parse(s).map_err(|e| e.to_string())
    }
    fn name_of(&self) -> String {
        self.name().into()
    }
}

impl Named for Normalise {
    fn parse_name(s: &str) -> Result<Normalise, String> {
        Normalise::parse(s).map_err(|e| e.to_string())
    }
    fn name_of(&self) -> String {
        self.name().into()
    }
}

impl Named for Objective {
    fn parse_name(s: &str) -> Result<Objective, String> {
        Objective::parse(s).map_err(|e| e.to_string())
    }
    fn name_of(&self) -> String {
        self.name()
    }
}

impl Named for Ridge {
    fn parse_name(s: &str) -> Result<Ridge, String> {
        Ridge::parse(s).map_err(|e| e.to_string())
    }
    /// `0` (no ridge, asked for), λ (written so that it reads back exactly), `auto`, `auto-loo`.
    fn name_of(&self) -> String {
        match self {
            Ridge::None => "0".into(),
            Ridge::Lambda(v) => v.to_string(),
            Ridge::Auto => "auto".into(),
            Ridge::AutoLoo => "auto-loo".into(),
        }
    }
}

impl Named for ChartKind {
    fn parse_name(s: &str) -> Result<ChartKind, String> {
        ChartKind::parse(s)
            .map_err(|_| format!("chart `{s}`: one of {}", crate::capture::chart_names()))
    }
    fn name_of(&self) -> String {
        self.name().into()
    }
}

/// The flat field of a reading (`--flat`): none, the chart's neutrals, a listed file (by its
/// index) or the flat frame uploaded for the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Flat {
    None,
    Neutrals,
    File(usize),
    Upload,
}

impl Named for Flat {
    fn parse_name(s: &str) -> Result<Flat, String> {
        match s.trim() {
            "" | "none" => Ok(Flat::None),
            "upload" => Ok(Flat::Upload),
            f if f.eq_ignore_ascii_case("neutrals") => Ok(Flat::Neutrals),
            f => f
                .strip_prefix("file:")
                .and_then(|n| n.parse().ok())
                .map(Flat::File)
                .ok_or_else(|| {
                    format!(
                        "flat `{f}`: none, neutrals, file:N (a listed file) or upload (the uploaded flat frame)"
                    )
                }),
        }
    }
    fn name_of(&self) -> String {
        match self {
            Flat::None => "none".into(),
            Flat::Neutrals => "neutrals".into(),
            Flat::File(i) => format!("file:{i}"),
            Flat::Upload => "upload".into(),
        }
    }
}

/// A [`Named`] value from its name.
fn de_named<'de, D: Deserializer<'de>, T: Named>(d: D) -> Result<T, D::Error> {
    let s = String::deserialize(d)?;
    T::parse_name(&s).map_err(D::Error::custom)
}

/// An optional [`Named`] value: `null` or a blank name is none.
fn de_named_opt<'de, D: Deserializer<'de>, T: Named>(d: D) -> Result<Option<T>, D::Error> {
    match Option::<String>::deserialize(d)? {
        Some(s) if !s.trim().is_empty() => T::parse_name(&s).map(Some).map_err(D::Error::custom),
        _ => Ok(None),
    }
}

fn ser_named_opt<S: Serializer, T: Named>(v: &Option<T>, s: S) -> Result<S::Ok, S::Error> {
    match v {
        Some(v) => s.serialize_str(&v.name_of()),
        None => s.serialize_none(),
    }
}

/// How the chart in a frame is read (the page's controls; the CLI's capture flags). The page
/// sends back the settings of the last answer with its changes.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Settings {
    #[serde(default = "default_chart", deserialize_with = "de_named")]
    pub(crate) chart: ChartKind,
    /// A built-in reference's name, or `upload` (the reference file uploaded for the frame).
    #[serde(default)]
    pub(crate) reference: Option<String>,
    /// X,Y,Z, x,y, `D50` or a built-in illuminant's name.
    #[serde(default)]
    pub(crate) reference_white: Option<String>,
    /// The four outer corners of the patch grid (first patch's corner first, clockwise); `None`:
    /// detect.
    #[serde(default)]
    pub(crate) corners: Option<[[f64; 2]; 4]>,
    /// Patches left out of the fit by hand (labels).
    #[serde(default)]
    pub(crate) exclude: Vec<String>,
    #[serde(
        default,
        deserialize_with = "de_named_opt",
        serialize_with = "ser_named_opt"
    )]
    pub(crate) flat: Option<Flat>,
    #[serde(default)]
    pub(crate) white_level: Option<f64>,
    #[serde(default)]
    pub(crate) layer: Option<String>,
}

fn default_chart() -> ChartKind {
    ChartKind::Cc24
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            chart: default_chart(),
            reference: None,
            reference_white: None,
            corners: None,
            exclude: Vec::new(),
            flat: None,
            white_level: None,
            layer: None,
        }
    }
}

/// A fit (or comparison) request: the kind, the order and the variant (the `fit` flags).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FitRequest {
    #[serde(default = "default_kind", deserialize_with = "de_named")]
    pub(crate) kind: Kind,
    #[serde(default = "default_order")]
    pub(crate) order: u8,
    #[serde(default = "default_objective", deserialize_with = "de_named")]
    pub(crate) objective: Objective,
    #[serde(default)]
    pub(crate) preserve_white: bool,
    #[serde(default)]
    pub(crate) white_patch: Option<String>,
    /// `None`: no ridge named (the f32 guard may add one); `Some(Ridge::None)`: `0`, none at all.
    #[serde(default, deserialize_with = "de_named_opt")]
    pub(crate) ridge: Option<Ridge>,
    #[serde(default, deserialize_with = "de_named")]
    pub(crate) normalise: Normalise,
}

fn default_kind() -> Kind {
    Kind::Nsrm
}
fn default_order() -> u8 {
    3
}
fn default_objective() -> Objective {
    Objective::LeastSquares
}

/// `GET /api/info`: what the page offers.
#[derive(Debug, Serialize)]
pub(crate) struct Info {
    pub(crate) version: &'static str,
    pub(crate) files: Vec<ListedFile>,
    pub(crate) charts: Vec<&'static str>,
    pub(crate) references: Vec<&'static str>,
    pub(crate) formats: Vec<&'static str>,
    pub(crate) spaces: Vec<&'static str>,
    pub(crate) kinds: Vec<&'static str>,
    pub(crate) max_pixels: u64,
    pub(crate) max_upload_bytes: u64,
    pub(crate) server_device: &'static str,
}

/// A frame named on the command line.
#[derive(Debug, Serialize)]
pub(crate) struct ListedFile {
    pub(crate) index: usize,
    pub(crate) name: String,
}

/// An open frame as the page shows it (the answer of every request that changes the reading).
#[derive(Debug, Serialize)]
pub(crate) struct State {
    pub(crate) id: String,
    pub(crate) name: String,
    /// `upload` or `file`.
    pub(crate) source: &'static str,
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) preview: Preview,
    pub(crate) settings: Settings,
    pub(crate) error: Option<String>,
    /// The chart reading (`nsrm-chart-reading`, as `chart extract --json` writes it).
    pub(crate) reading: Option<Value>,
    pub(crate) patches_spec: Option<String>,
    pub(crate) flat_upload: Option<String>,
    pub(crate) reference_upload: Option<String>,
    pub(crate) fitted: Option<FittedBrief>,
    pub(crate) command: String,
}

/// The frame's preview image.
#[derive(Debug, Serialize)]
pub(crate) struct Preview {
    pub(crate) url: String,
    pub(crate) scale: usize,
}

/// The last fit of a frame, in a state.
#[derive(Debug, Serialize)]
pub(crate) struct FittedBrief {
    /// As the kind is displayed: `NSRM`.
    pub(crate) kind: String,
    pub(crate) order: u8,
    pub(crate) report: FitReport,
}

/// `POST …/fit`: the model file, its report and its errors on the training patches.
#[derive(Debug, Serialize)]
pub(crate) struct FitAnswer {
    /// The model file's JSON.
    pub(crate) model: Value,
    /// As the kind is displayed: `NSRM`.
    pub(crate) kind: String,
    pub(crate) order: u8,
    pub(crate) terms: usize,
    pub(crate) report: FitReport,
    pub(crate) n_patches: usize,
    pub(crate) patches_spec: String,
    pub(crate) in_sample: Stats,
    pub(crate) patches: Vec<PatchFit>,
    pub(crate) command: String,
}

/// One training patch of a fit.
#[derive(Debug, Serialize)]
pub(crate) struct PatchFit {
    pub(crate) label: String,
    pub(crate) rgb: [f64; 3],
    pub(crate) reference_xyz: [f64; 3],
    pub(crate) corrected_xyz: [f64; 3],
    pub(crate) reference_srgb8: [u8; 3],
    pub(crate) corrected_srgb8: [u8; 3],
    #[serde(rename = "dE00")]
    pub(crate) de00: f64,
}

/// `POST …/compare`: every kind and order, leave-one-out and in sample.
#[derive(Debug, Serialize)]
pub(crate) struct Comparison {
    pub(crate) leave_one_out: Vec<Evaluated>,
    pub(crate) in_sample: Vec<Evaluated>,
    /// The best by leave-one-out mean.
    pub(crate) best: Option<Best>,
    pub(crate) n_patches: usize,
    /// One `nsrm eval` line per kind.
    pub(crate) command: String,
}

/// One kind and order of a comparison: its evaluation (as `eval --json` writes it), or why it
/// could not be fitted.
#[derive(Debug, Serialize)]
#[serde(untagged)]
pub(crate) enum Evaluated {
    Done(EvalResult),
    Failed {
        model: String,
        order: u8,
        error: String,
    },
}

/// The best of a comparison.
#[derive(Debug, Serialize)]
pub(crate) struct Best {
    pub(crate) model: String,
    pub(crate) order: u8,
    pub(crate) mean: f64,
}

/// `GET …/shader`: the generated WGSL and how to show its output.
#[derive(Debug, Serialize)]
pub(crate) struct Shader {
    pub(crate) wgsl: String,
    pub(crate) to_linear_srgb: Mat3,
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) workgroup_size: u32,
}

/// The body of every error answer.
#[derive(Debug, Serialize)]
pub(crate) struct ErrorBody {
    pub(crate) error: String,
}

/// `DELETE /api/frames/ID`.
#[derive(Debug, Serialize)]
pub(crate) struct Closed<'a> {
    pub(crate) closed: &'a str,
}

#[cfg(test)]
#[path = "wire_tests.rs"]
mod tests;
