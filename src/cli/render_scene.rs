//! `nsrm render-scene`: a synthetic photo of a chart (projective pose, clutter, uneven light,
//! blur, noise, clipping, optional occlusion) with its ground truth beside it.

use super::common::UsageError;
use super::values;
use anyhow::{Context, Result};
use nsrm::chart::scene::{render, truth_path, ChartColours, SceneOptions};
use nsrm::chart::{parse_corners, ChartKind};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// cc24 (built-in BabelColor spectra) or sg (spectra from --reflectances).
    #[arg(long, value_enum, ignore_case = true)]
    chart: values::Chart,
    /// Chart spectra: columns named by chart labels (SG: A1..N10, e.g.
    /// ../shared/data/colorchecker_sg_140.csv); default for cc24: the built-in cc24.
    #[arg(long, value_name = "FILE")]
    reflectances: Option<String>,
    #[arg(long, default_value = "nikon-d5100", value_name = "NAME|FILE")]
    camera: String,
    #[arg(long, default_value = "D65", value_name = "NAME|FILE")]
    illuminant: String,
    #[arg(long, default_value_t = 1200)]
    width: usize,
    #[arg(long, default_value_t = 800)]
    height: usize,
    /// Place the patch grid at these corners ("X,Y X,Y X,Y X,Y", first patch first, clockwise);
    /// default: a random pose from --seed.
    #[arg(long, allow_hyphen_values = true)]
    corners: Option<String>,
    /// A random scene inside the detection envelope (exposure, light, blur and noise drawn from
    /// --seed too; the options below are then ignored).
    #[arg(long)]
    envelope: bool,
    /// A scene of one of `chart rate`'s families (implies --envelope's draws): jpeg, fill, small,
    /// passport, or the negatives spyder, random, shuffled (cc24). A jpeg-look scene is written
    /// as the values nsrm decodes from the camera JPEG (sRGB decoded, tone curve kept).
    #[arg(long, value_parser = super::chart::parse_family, conflicts_with = "envelope")]
    family: Option<nsrm::chart::scene::Family>,
    #[arg(long, default_value_t = 1)]
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
    /// Background shapes.
    #[arg(long, default_value_t = 20)]
    clutter: usize,
    /// Hide a corner of the chart behind an object.
    #[arg(long)]
    occlusion: bool,
    /// Random pose: chart area fraction range and largest tilt.
    #[arg(long, default_value_t = 0.1)]
    min_area: f64,
    #[arg(long, default_value_t = 0.4)]
    max_area: f64,
    #[arg(long, default_value_t = 30.0)]
    max_tilt: f64,
    /// Also write a flat frame (a grey card under the same light) here.
    #[arg(long, value_name = "FILE")]
    flat_output: Option<PathBuf>,
    /// The frame: .exr or .tif/.tiff. The truth goes to NAME.scene.json beside it.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[arg(long)]
    overwrite: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let kind = ChartKind::from(a.chart);
    for p in std::iter::once(&a.output).chain(&a.flat_output) {
        if nsrm::io::FileFormat::from_extension(p).is_none() {
            return Err(UsageError(format!("{}: must be .exr, .tif or .tiff", p.display())).into());
        }
        nsrm::atomic::check_clobber(p, a.overwrite)?;
    }
    let tpath = truth_path(&a.output);
    nsrm::atomic::check_clobber(&tpath, a.overwrite)?;
    let corners = a.corners.as_deref().map(parse_corners).transpose()?;
    let colours =
        ChartColours::simulate(kind, &a.camera, &a.illuminant, a.reflectances.as_deref())?;
    let (colours, opts) = if let Some(f) = a.family {
        if f.negative() && kind != ChartKind::Cc24 {
            return Err(UsageError(format!(
                "--family {}: the negative families are cc24 layouts",
                f.name()
            ))
            .into());
        }
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
            ..Default::default()
        };
        (colours, o)
    };
    let (frame, flat, truth) = render(&colours, &opts)?;
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
    nsrm::io::chart::write_camera_frame(&frame, &a.output, &note, a.overwrite)
        .with_context(|| format!("writing {}", a.output.display()))?;
    if let Some(f) = &a.flat_output {
        nsrm::io::chart::write_camera_frame(&flat, f, "nsrm scene: flat frame", a.overwrite)
            .with_context(|| format!("writing {}", f.display()))?;
    }
    nsrm::atomic::write_atomic(&tpath, json.as_bytes(), a.overwrite)?;
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
