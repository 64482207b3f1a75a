//! `nsrm render-scene`: a synthetic photo of a chart (projective pose, clutter, uneven light,
//! blur, noise, clipping, optional occlusion) with its ground truth beside it.

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm_chart::parse_corners;
use nsrm_chart::scene::{render, truth_path, ChartColours, SceneOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// cc24 (built-in BabelColor spectra), sg (spectra from --reflectances) or spyder24 (the
    /// classic's built-in spectra in the SpyderCHECKR's layout, or --reflectances).
    #[arg(long, value_enum, ignore_case = true)]
    chart: nsrm_chart::ChartKind,
    /// Chart spectra: columns named by chart labels (SG: A1..N10, e.g.
    /// ../shared/data/colorchecker_sg_140.csv); default for cc24: the built-in cc24.
    #[arg(long, value_name = "FILE")]
    reflectances: Option<String>,
    /// Camera sensitivities: a built-in name (nikon-d5100) or a CSV file (wavelength, R, G, B).
    #[arg(long, default_value = "nikon-d5100", value_name = "NAME|FILE")]
    camera: String,
    /// Illuminant the chart is lit by: a built-in name or a CSV file.
    #[arg(long, default_value = "D65", value_name = "NAME|FILE")]
    illuminant: String,
    /// Frame width in pixels.
    #[arg(long, default_value_t = 1200, value_name = "PX")]
    width: usize,
    /// Frame height in pixels.
    #[arg(long, default_value_t = 800, value_name = "PX")]
    height: usize,
    /// Place the patch grid at these corners ("X,Y X,Y X,Y X,Y", first patch first, clockwise);
    /// default: a random pose from --seed.
    #[arg(long, allow_hyphen_values = true, value_name = "CORNERS")]
    corners: Option<String>,
    /// A random scene inside the detection envelope (exposure, light, blur and noise drawn from
    /// --seed too; the options below are then ignored).
    #[arg(long)]
    envelope: bool,
    /// A scene of one of `chart rate`'s families (implies --envelope's draws): jpeg, fill, small,
    /// passport, tilt, black-frame, wide, graded, noisy, litter, or the negatives spyder, random, shuffled (in the
    /// chart's layout), nested (an SG-like chart holding the CC24's colours; for sg, a CC24 of
    /// the SG's E2–J5 block), spyder24 (a SpyderCHECKR 24). A jpeg-look scene is written as the
    /// values nsrm decodes from the camera JPEG (sRGB decoded, tone curve kept).
    #[arg(long, value_parser = super::chart::parse_family, conflicts_with = "envelope")]
    family: Option<nsrm_chart::scene::Family>,
    /// Seed of the random pose, clutter and noise (and, with --envelope, of everything).
    #[arg(long, default_value_t = 1, value_name = "N")]
    seed: u64,
    /// Multiplies camera RGB (the evenly lit perfect white has G = exposure).
    #[arg(long, default_value_t = 0.8)]
    exposure: f64,
    /// Clipping level.
    #[arg(long, default_value_t = 1.0)]
    white_level: f64,
    /// Additive noise σ.
    #[arg(long, default_value_t = 0.001)]
    noise: f64,
    /// Shot noise: variance per unit signal.
    #[arg(long, default_value_t = 0.0)]
    shot_noise: f64,
    /// Gaussian blur σ in pixels.
    #[arg(long, default_value_t = 0.0)]
    blur: f64,
    /// Light fall-off at the frame corners (0..1).
    #[arg(long, default_value_t = 0.0)]
    vignetting: f64,
    /// Linear light gradient across the frame (0..1).
    #[arg(long, default_value_t = 0.0)]
    gradient: f64,
    /// Background shapes (the envelope's 25).
    #[arg(long, default_value_t = 25, value_name = "N")]
    clutter: usize,
    /// Hide a corner of the chart behind an object.
    #[arg(long)]
    occlusion: bool,
    /// Random pose: smallest chart area, a fraction of the frame (the envelope's 0.05).
    #[arg(long, default_value_t = 0.05, value_name = "F")]
    min_area: f64,
    /// Random pose: largest chart area, a fraction of the frame (the envelope's 0.4).
    #[arg(long, default_value_t = 0.4, value_name = "F")]
    max_area: f64,
    /// Random pose: largest tilt in degrees (the envelope's 30).
    #[arg(long, default_value_t = 30.0, value_name = "DEG")]
    max_tilt: f64,
    /// Random pose: smallest tilt in degrees; the tilt is drawn from MIN..MAX.
    #[arg(long, default_value_t = 0.0, value_name = "DEG")]
    min_tilt: f64,
    /// Also write a flat frame (a grey card under the same light) here.
    #[arg(long, value_name = "FILE")]
    flat_output: Option<PathBuf>,
    /// The frame: .exr or .tif/.tiff. The truth goes to NAME.scene.json beside it.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let kind = a.chart;
    for p in std::iter::once(&a.output).chain(&a.flat_output) {
        if nsrm_io::FileFormat::from_extension(p).is_none() {
            return Err(UsageError(format!("{}: must be .exr, .tif or .tiff", p.display())).into());
        }
    }
    let tpath = truth_path(&a.output);
    let inputs: Vec<&Path> = [
        Some(a.camera.as_str()),
        Some(a.illuminant.as_str()),
        a.reflectances.as_deref(),
    ]
    .into_iter()
    .flatten()
    .filter_map(super::outputs::file_arg)
    .collect();
    let mut outputs = vec![a.output.as_path(), tpath.as_path()];
    outputs.extend(a.flat_output.as_deref());
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &outputs)?;
    let corners = a.corners.as_deref().map(parse_corners).transpose()?;
    let colours =
        ChartColours::simulate(kind, &a.camera, &a.illuminant, a.reflectances.as_deref())?;
    let (colours, opts) = if let Some(f) = a.family {
        let (c, mut o) = f.scene(&colours, a.width, a.height, a.seed);
        o.corners = corners.or(o.corners);
        (c, o)
    } else if a.envelope {
        let o = SceneOptions {
            corners,
            ..SceneOptions::envelope(&colours, a.width, a.height, a.seed)
        };
        (colours, o)
    } else {
        let o = SceneOptions {
            width: a.width,
            height: a.height,
            corners,
            seed: a.seed,
            exposure: a.exposure,
            white_level: a.white_level,
            noise: a.noise,
            shot_noise: a.shot_noise,
            blur: a.blur,
            vignetting: a.vignetting,
            gradient: a.gradient,
            clutter: a.clutter,
            occlusion: a.occlusion,
            min_area: a.min_area,
            max_area: a.max_area,
            max_tilt_deg: a.max_tilt,
            min_tilt_deg: a.min_tilt,
            ..Default::default()
        };
        (colours, o)
    };
    let (frame, flat, mut truth) = render(&colours, &opts)?;
    if let Some(f) = a.family.filter(|f| f.negative()) {
        // The chart drawn is not the one named: its cells carry none of that chart's labels.
        truth.patches.clear();
        truth.impostor = Some(f.name().to_string());
    }
    let json = serde_json::to_string_pretty(&truth)?;
    let note = format!(
        "nsrm scene: {} chart, seed {}, camera {}, illuminant {}; {}",
        kind.name(),
        truth.seed,
        truth.camera,
        truth.illuminant,
        if opts.look.is_some() {
            "camera JPEG rendering, sRGB decoded"
        } else {
            "linear camera RGB"
        }
    );
    let mut unit = session.unit();
    unit.write_with(&a.output, |w| {
        nsrm_chart::synthetic::write_camera_frame(&frame, &a.output, &note, w)
    })
    .with_context(|| format!("writing {}", a.output.display()))?;
    if let Some(f) = &a.flat_output {
        unit.write_with(f, |w| {
            nsrm_chart::synthetic::write_camera_frame(&flat, f, "nsrm scene: flat frame", w)
        })
        .with_context(|| format!("writing {}", f.display()))?;
    }
    unit.write_bytes(&tpath, json.as_bytes())?;
    unit.commit()?;
    eprintln!(
        "{} chart rendered to {} ({}×{}; area {:.1} %, rotation {:.0}°, tilt {:.0}°, exposure {:.3}); truth in {}",
        kind.name(),
        a.output.display(),
        truth.width,
        truth.height,
        100.0 * truth.area_fraction,
        truth.rotation_deg,
        truth.tilt_deg,
        truth.exposure,
        tpath.display()
    );
    Ok(ExitCode::SUCCESS)
}
