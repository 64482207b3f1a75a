//! `nsrm chart`: read a photographed chart (`extract`), and measure detection over seeded
//! synthetic scenes (`rate`).

use super::capture::{write_overlay, CaptureOptions, CaptureText};
use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm_chart::detect::{detect, DetectFailure, DetectOptions, Detection};
use nsrm_chart::extract::{extract, ExtractOptions, Extraction, PatchReading};
use nsrm_chart::reference::Reference;
use nsrm_chart::scene::{render, ChartColours, Family, SceneOptions, SceneTruth, TruePatch};
use nsrm_chart::{ChartError, ChartKind};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Subcommand)]
pub(crate) enum Command {
    /// Read the patches of a chart in a frame (camera raw, linear EXR/TIFF, or a JPEG/PNG) and
    /// write them as `label,R,G,B,X,Y,Z`
    /// (the format `--training` reads; flagged patches are left out with a warning).
    Extract(ExtractArgs),
    /// Detection rate (and time) over seeded synthetic scenes inside the detection envelope.
    Rate(RateArgs),
    /// Time detection + extraction on frames (the file read is not timed): one JSON line per
    /// frame with the median of --repeat runs and what was found.
    Time(TimeArgs),
}

#[derive(Debug, clap::Args)]
pub(crate) struct TimeArgs {
    /// The frames.
    #[arg(value_name = "FRAME", required = true)]
    frames: Vec<PathBuf>,
    /// cc24, sg or spyder24.
    #[arg(long, value_enum, ignore_case = true)]
    chart: nsrm_chart::ChartKind,
    /// How the frames' values are encoded (as in `chart extract`).
    #[arg(long, value_enum, ignore_case = true, default_value = "auto")]
    encoding: super::capture::EncodingArg,
    /// Runs per frame.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    #[command(flatten)]
    max_pixels: super::values::MaxPixelsArg,
}

#[derive(Debug, clap::Args)]
pub(crate) struct ExtractArgs {
    /// The frame: a camera raw file (DNG, CR2, CR3, NEF, ARW, …), a linear EXR or TIFF, or a
    /// display-referred JPEG, PNG or 8-bit TIFF (see --encoding).
    #[arg(value_name = "FRAME")]
    frame: PathBuf,
    #[command(flatten)]
    capture: CaptureOptions,
    /// The patches CSV to write.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Also write the full report (every patch with std, count, flags; pose; detection) as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Draw the sampled areas (or, when no chart is found, the rejected candidates) on an sRGB
    /// preview of the frame.
    #[arg(long, value_name = "FILE.png")]
    overlay: Option<PathBuf>,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
}

#[derive(Debug, clap::Args)]
pub(crate) struct RateArgs {
    /// The chart: cc24, sg or spyder24.
    #[arg(long, value_enum, ignore_case = true)]
    chart: nsrm_chart::ChartKind,
    /// Spectra of the chart (SG: e.g. ../shared/data/colorchecker_sg_140.csv).
    #[arg(long, value_name = "FILE")]
    reflectances: Option<String>,
    /// Camera sensitivities: a built-in name (nikon-d5100) or a CSV file (wavelength, R, G, B).
    #[arg(long, default_value = "nikon-d5100", value_name = "NAME|FILE")]
    camera: String,
    /// Illuminant the chart is lit by: a built-in name or a CSV file.
    #[arg(long, default_value = "D65", value_name = "NAME|FILE")]
    illuminant: String,
    /// Number of scenes.
    #[arg(long, default_value_t = 200, value_name = "N")]
    scenes: u64,
    /// First seed.
    #[arg(long, default_value_t = 1, value_name = "N")]
    seed: u64,
    /// Frame width in pixels.
    #[arg(long, default_value_t = 1200, value_name = "PX")]
    width: usize,
    /// Frame height in pixels.
    #[arg(long, default_value_t = 800, value_name = "PX")]
    height: usize,
    /// Print each failure.
    #[arg(long)]
    verbose: bool,
    /// Leave the envelope on purpose: smallest chart area (fraction of the frame; envelope 0.05).
    #[arg(long, value_name = "F")]
    min_area: Option<f64>,
    /// Largest chart area (envelope 0.4).
    #[arg(long, value_name = "F")]
    max_area: Option<f64>,
    /// Largest tilt in degrees (envelope 30).
    #[arg(long, value_name = "DEG")]
    max_tilt: Option<f64>,
    /// Smallest tilt in degrees (default 0): the tilt is drawn from MIN..MAX.
    #[arg(long, value_name = "DEG")]
    min_tilt: Option<f64>,
    /// Largest exposure below clipping of the brightest patch, in stops: drawn from 0..S
    /// (envelope 4; `--stops` is the old spelling).
    #[arg(long, alias = "stops", value_name = "S")]
    max_stops: Option<f64>,
    /// Smallest exposure below clipping in stops (default 0): drawn from MIN..S.
    #[arg(long, value_name = "S")]
    min_stops: Option<f64>,
    /// Blur σ in pixels drawn from 0..B (envelope 1.2).
    #[arg(long, value_name = "B")]
    max_blur: Option<f64>,
    /// Smallest blur σ in pixels (default 0): drawn from MIN..B.
    #[arg(long, value_name = "B")]
    min_blur: Option<f64>,
    /// Hide a corner of the chart behind an object.
    #[arg(long)]
    occlusion: bool,
    /// The family of scenes: envelope (plain linear scenes), jpeg (through a camera's tone
    /// curve, saturation and JPEG), fill (the chart filling the frame), small (small, a corner
    /// covered), passport (the Passport's second page beside the chart), tilt (tilted 30–50°),
    /// black-frame (the chart body as dark as its black patch), wide (a wide-angle camera close
    /// to the chart: perspective 1.6–2.2), graded (a strong contrast curve and saturation boost),
    /// noisy (a large frontal chart under very high-ISO noise), litter (a tiny chart on leaf
    /// litter); negatives, which must all be refused, in the
    /// chart's layout: spyder (another make's chart: a SpyderCHECKR-24-like one, for sg a
    /// 14×10 one with a grey ramp in two columns), random (random patch grids), shuffled (the
    /// chart's greys in place, its colours in another order), nested (for cc24 an SG-like
    /// 14×10 chart holding the classic 24 in its E2–J5 block, as the SG does; for sg a CC24 made
    /// of that block) and spyder24 (a Datacolor SpyderCHECKR 24: the classic colours, rows 1 and
    /// 3 reversed; for sg that chart made of the SG's E2–J5 block).
    #[arg(long, default_value = "envelope", value_parser = parse_family)]
    family: Family,
}

pub(crate) fn parse_family(s: &str) -> std::result::Result<Family, String> {
    Family::parse(s).ok_or_else(|| {
        let names: Vec<&str> = Family::ALL.iter().map(|f| f.name()).collect();
        format!("unknown family `{s}` (known: {})", names.join(", "))
    })
}

pub(crate) fn run(c: Command) -> Result<ExitCode> {
    match c {
        Command::Extract(a) => run_extract(a),
        Command::Rate(a) => run_rate(a),
        Command::Time(a) => run_time(a),
    }
}

fn run_time(a: TimeArgs) -> Result<ExitCode> {
    let kind = a.chart;
    let reference = Reference::load(kind.default_reference(), kind, None)?;
    let opts = nsrm_io::ReadOptions {
        limits: nsrm_io::Limits {
            max_pixels: a.max_pixels.max_pixels,
        },
        ..Default::default()
    };
    let mut failed = 0;
    for path in &a.frames {
        let read = match nsrm_io::display::read_chart_frame(path, &opts, a.encoding.into()) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("error: {e}");
                failed += 1;
                continue;
            }
        };
        let ex_opts = ExtractOptions {
            quantisation: nsrm_chart::extract::Quantisation::of(&read),
            ..Default::default()
        };
        let mut times = Vec::new();
        let mut outcome = String::new();
        for _ in 0..a.repeat {
            let t0 = Instant::now();
            let r = detect(&read.frame, &reference, &DetectOptions::default())
                .map_err(|f| f.error)
                .and_then(|d| {
                    extract(&read.frame, &reference, &d.homography, &ex_opts)
                        .and_then(|ex| nsrm_chart::extract::verify(&ex, &reference).map(|_| ex))
                });
            times.push(t0.elapsed().as_secs_f64());
            outcome = match r {
                Ok(ex) => format!(
                    "found: first patch at ({:.0}, {:.0})",
                    ex.patches[0].centre[0], ex.patches[0].centre[1]
                ),
                Err(e) => format!("refused: {e}"),
            };
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{}",
            serde_json::json!({
                "frame": path.display().to_string(),
                "width": read.frame.width,
                "height": read.frame.height,
                "encoding": read.transfer.describe(),
                "median_s": times[times.len() / 2],
                "runs": times.len(),
                "outcome": outcome,
            })
        );
    }
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

fn run_extract(a: ExtractArgs) -> Result<ExitCode> {
    a.capture.kinds()?;
    if let Some(o) = &a.overlay {
        if !o.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            return Err(UsageError(format!("--overlay {}: must be a .png", o.display())).into());
        }
    }
    let mut inputs = vec![a.frame.as_path()];
    inputs.extend(a.capture.input_files());
    let outputs: Vec<&Path> = std::iter::once(&a.output)
        .chain(&a.json)
        .chain(&a.overlay)
        .map(PathBuf::as_path)
        .collect();
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &outputs)?;
    let cap = a
        .capture
        .read(&a.frame, a.overlay.as_deref().map(|p| (p, &session)))?;
    // Everything is computed; now write, all together.
    let mut unit = session.unit();
    unit.write_bytes(&a.output, cap.to_csv().as_bytes())
        .with_context(|| format!("writing {}", a.output.display()))?;
    if let Some(j) = &a.json {
        let text = serde_json::to_string_pretty(&cap.report())?;
        unit.write_bytes(j, text.as_bytes())
            .with_context(|| format!("writing {}", j.display()))?;
    }
    if let Some(o) = &a.overlay {
        write_overlay(
            cap.frame.frame(),
            Some(&cap.extraction),
            &[],
            None,
            o,
            &mut unit,
        )?;
    }
    unit.commit()?;
    if let Some(w) = cap.other_chart_warning() {
        eprintln!("{w}");
    }
    eprintln!(
        "{}; written to {} (its `# white:` line names that white)",
        cap.summary(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `chart rate`: the arguments checked ([`check_rate_args`]), then per seed the family's scene
/// with the asked ranges ([`rate_options`]), rendered, detected and read (timed), and judged
/// against its truth ([`judge_negative`], [`judge_positive`]); last the tally.
fn run_rate(a: RateArgs) -> Result<ExitCode> {
    let kind = a.chart;
    check_rate_args(&a)?;
    let colours =
        ChartColours::simulate(kind, &a.camera, &a.illuminant, a.reflectances.as_deref())?;
    let reference = Reference::load(kind.default_reference(), kind, None)?;
    let clip_exposure = 1.0 / colours.rgb.iter().flatten().copied().fold(0.0, f64::max);
    let mut tally = [0u64; 3];
    let mut t_detect = Vec::new();
    for s in 0..a.scenes {
        let seed = a.seed + s;
        let (scene_colours, mut opts) = a.family.scene(&colours, a.width, a.height, seed);
        rate_options(&a, &mut opts, clip_exposure);
        let (frame, _, truth) = render(&scene_colours, &opts)?;
        let t0 = Instant::now();
        let found = detect(&frame, &reference, &DetectOptions::default());
        let result = found.map(|d| {
            let ex = extract(
                &frame,
                &reference,
                &d.homography,
                &ExtractOptions::default(),
            );
            (d, ex)
        });
        t_detect.push(t0.elapsed().as_secs_f64());
        let verdict = if a.family.negative() {
            judge_negative(&a, kind, seed, result)
        } else {
            judge_positive(&a, seed, &truth, result)
        };
        tally[verdict as usize] += 1;
    }
    let [ok, refused, wrong] = tally;
    t_detect.sort_by(f64::total_cmp);
    let n = a.scenes as f64;
    println!(
        "{} chart, family {}, {} scenes of {}×{} (seeds {}..{}): detected correctly {ok} ({:.1} %), refused {refused}, wrong {wrong}; detection + extraction median {:.0} ms, max {:.0} ms",
        kind.name(),
        a.family.name(),
        a.scenes,
        a.width,
        a.height,
        a.seed,
        a.seed + a.scenes - 1,
        100.0 * ok as f64 / n,
        1e3 * t_detect[t_detect.len() / 2],
        1e3 * t_detect[t_detect.len() - 1],
    );
    Ok(if wrong == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// What `chart rate` made of one scene (the index of its count in the tally).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    Ok = 0,
    Refused = 1,
    Wrong = 2,
}

/// What one scene's detection and extraction gave.
type RateResult =
    std::result::Result<(Detection, std::result::Result<Extraction, ChartError>), DetectFailure>;

/// The usage checks of `chart rate`: the scene count, the seed range and the ranges
/// ([`check_rate_ranges`]).
fn check_rate_args(a: &RateArgs) -> Result<()> {
    if a.scenes == 0 || a.scenes > 100_000 {
        return Err(UsageError("--scenes must be 1..100000".into()).into());
    }
    if a.seed.checked_add(a.scenes - 1).is_none() {
        return Err(UsageError(format!(
            "--seed {} + --scenes {}: the last seed would pass {} (the largest seed)",
            a.seed,
            a.scenes,
            u64::MAX
        ))
        .into());
    }
    check_rate_ranges(a)
}

/// A scene's options with the ranges `chart rate` was given: the area, tilt, exposure (stops
/// below `clip_exposure`) and blur drawn within them, and the occlusion.
fn rate_options(a: &RateArgs, opts: &mut SceneOptions, clip_exposure: f64) {
    opts.min_area = a.min_area.unwrap_or(opts.min_area);
    opts.max_area = a.max_area.unwrap_or(opts.max_area).max(opts.min_area);
    opts.max_tilt_deg = a.max_tilt.unwrap_or(opts.max_tilt_deg);
    // The family's own minimum (the tilt family's 30°) unless `--min-tilt` is given.
    opts.min_tilt_deg = a
        .min_tilt
        .unwrap_or(opts.min_tilt_deg)
        .min(opts.max_tilt_deg);
    if a.max_stops.is_some() || a.min_stops.is_some() {
        // Same draw as the envelope's (u uniform in 0..1, 4·u stops below clipping),
        // rescaled to MIN..S stops.
        let u = -(opts.exposure / clip_exposure).log2() / 4.0;
        let (lo, hi) = (a.min_stops.unwrap_or(0.0), a.max_stops.unwrap_or(4.0));
        opts.exposure = clip_exposure * 2f64.powf(-(lo + (hi - lo).max(0.0) * u));
    }
    if a.max_blur.is_some() || a.min_blur.is_some() {
        let u = opts.blur / 1.2;
        let (lo, hi) = (a.min_blur.unwrap_or(0.0), a.max_blur.unwrap_or(1.2));
        opts.blur = lo + (hi - lo).max(0.0) * u;
    }
    opts.occlusion |= a.occlusion;
}

/// A scene of a negative family: any chart found is wrong (and said), a refusal right.
fn judge_negative(a: &RateArgs, kind: ChartKind, seed: u64, result: RateResult) -> Verdict {
    match result {
        Ok((d, _)) => {
            eprintln!(
                "seed {seed}: WRONG: a {} chart reported in a {} scene (score {:.2}, runner-up {:.2}, lattice {})",
                kind.name(),
                a.family.name(),
                d.score,
                d.runner_up,
                d.lattice
            );
            Verdict::Wrong
        }
        Err(f) => {
            if a.verbose {
                eprintln!("seed {seed}: refused: {}", f.error);
            }
            Verdict::Refused
        }
    }
}

/// How many read patches are misplaced — another label, or a sampled centre more than a quarter
/// of `pitch` from the true centre — and the largest centre error, in pitches.
fn misplaced(patches: &[PatchReading], truth: &[TruePatch], pitch: f64) -> (usize, f64) {
    let off = |p: &PatchReading, t: &TruePatch| {
        (p.centre[0] - t.centre[0]).hypot(p.centre[1] - t.centre[1])
    };
    let bad = patches
        .iter()
        .zip(truth)
        .filter(|(p, t)| p.label != t.label || off(p, t) > 0.25 * pitch)
        .count();
    let worst = patches
        .iter()
        .zip(truth)
        .map(|(p, t)| off(p, t))
        .fold(0.0, f64::max)
        / pitch;
    (bad, worst)
}

/// A scene of the chart asked for: right when every label is in its true cell (each sampled
/// centre within a quarter pitch of the true one), wrong (and said) otherwise; a refusal is
/// said with `--verbose`.
fn judge_positive(a: &RateArgs, seed: u64, truth: &SceneTruth, result: RateResult) -> Verdict {
    // The perspective of the true pose, as the detector's limit measures it.
    let true_persp = nsrm_chart::detect::perspective(truth.chart, &truth.homography);
    match result {
        Ok((d, Ok(ex))) => {
            let (bad, worst) = misplaced(&ex.patches, &truth.patches, pitch_px(truth));
            if bad == 0 {
                if a.verbose {
                    eprintln!(
                        "seed {seed}: ok (score {:.2}, runner-up {:.2}, lattice {}, worst centre {worst:.2} pitch, perspective {:.3}, true {true_persp:.3})",
                        d.score, d.runner_up, d.lattice, d.perspective
                    );
                }
                Verdict::Ok
            } else {
                eprintln!(
                    "seed {seed}: WRONG: {bad} patches in the wrong cell (score {:.2}, runner-up {:.2}, lattice {}, worst centre {worst:.2} pitch, perspective {:.3}, true {true_persp:.3}; area {:.3}, tilt {:.0}°, blur {:.2})",
                    d.score, d.runner_up, d.lattice, d.perspective, truth.area_fraction, truth.tilt_deg, truth.blur
                );
                Verdict::Wrong
            }
        }
        Ok((_, Err(e))) => {
            if a.verbose {
                eprintln!("seed {seed}: refused: {e} (true perspective {true_persp:.3})");
            }
            Verdict::Refused
        }
        Err(f) => {
            if a.verbose {
                eprintln!(
                    "seed {seed}: refused: {} (area {:.3}, tilt {:.0}°, exposure {:.3}, true perspective {true_persp:.3})",
                    f.error, truth.area_fraction, truth.tilt_deg, truth.exposure
                );
            }
            Verdict::Refused
        }
    }
}

/// The scene ranges of `chart rate`: each a finite number ≥ 0 (areas in (0, 0.9], tilts up to
/// 60°, blur up to 20 px), and each MIN at most its MAX — never clamped silently.
fn check_rate_ranges(a: &RateArgs) -> Result<()> {
    let limits: [(&str, Option<f64>, f64); 8] = [
        ("--min-area", a.min_area, 0.9),
        ("--max-area", a.max_area, 0.9),
        ("--min-tilt", a.min_tilt, 60.0),
        ("--max-tilt", a.max_tilt, 60.0),
        ("--min-stops", a.min_stops, 100.0),
        ("--max-stops", a.max_stops, 100.0),
        ("--min-blur", a.min_blur, 20.0),
        ("--max-blur", a.max_blur, 20.0),
    ];
    for (flag, v, hi) in limits {
        if let Some(v) = v {
            if !(v.is_finite() && (0.0..=hi).contains(&v)) {
                return Err(UsageError(format!("{flag} {v}: must be a number in 0..{hi}")).into());
            }
        }
    }
    if a.min_area == Some(0.0) {
        return Err(UsageError("--min-area 0: a chart needs some area".into()).into());
    }
    // The defaults are the envelope's (SceneOptions::envelope).
    let pairs = [
        (
            "--min-area",
            a.min_area,
            "--max-area",
            a.max_area,
            0.05,
            0.4,
        ),
        (
            "--min-tilt",
            a.min_tilt,
            "--max-tilt",
            a.max_tilt,
            0.0,
            30.0,
        ),
        (
            "--min-stops",
            a.min_stops,
            "--max-stops",
            a.max_stops,
            0.0,
            4.0,
        ),
        ("--min-blur", a.min_blur, "--max-blur", a.max_blur, 0.0, 1.2),
    ];
    for (lo_flag, lo, hi_flag, hi, lo_default, hi_default) in pairs {
        let (l, h) = (lo.unwrap_or(lo_default), hi.unwrap_or(hi_default));
        if l > h {
            return Err(UsageError(format!(
                "{lo_flag} {l} is above {hi_flag} {h}{}",
                if hi.is_none() || lo.is_none() {
                    " (its default)"
                } else {
                    ""
                }
            ))
            .into());
        }
    }
    Ok(())
}

/// The patch pitch in frame pixels near the chart's centre.
pub(crate) fn pitch_px(t: &nsrm_chart::scene::SceneTruth) -> f64 {
    let c = [t.chart.columns() as f64 / 2.0, t.chart.rows() as f64 / 2.0];
    let a = t.homography.apply(c);
    let b = t.homography.apply([c[0] + 1.0, c[1]]);
    let d = t.homography.apply([c[0], c[1] + 1.0]);
    (a[0] - b[0])
        .hypot(a[1] - b[1])
        .min((a[0] - d[0]).hypot(a[1] - d[1]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Rate {
        #[command(flatten)]
        a: RateArgs,
    }

    fn args(extra: &[&str]) -> RateArgs {
        let argv = ["rate", "--chart", "cc24"]
            .into_iter()
            .chain(extra.iter().copied());
        Rate::try_parse_from(argv).unwrap().a
    }

    #[test]
    fn rate_ranges_rescale_the_scenes_own_draws() {
        let mut o = SceneOptions {
            exposure: 0.25,
            blur: 0.6,
            ..SceneOptions::default()
        };
        let before = o.clone();
        rate_options(&args(&[]), &mut o, 1.0);
        assert_eq!(o, before, "no range given: the family's scene");
        // Two stops under clipping of 0..4 is the middle; of 0..2 it becomes one stop.
        rate_options(
            &args(&["--max-stops", "2", "--max-blur", "2.4"]),
            &mut o,
            1.0,
        );
        assert!((o.exposure - 0.5).abs() < 1e-12, "{}", o.exposure);
        assert!((o.blur - 1.2).abs() < 1e-12, "{}", o.blur);
        let a = args(&["--min-area", "0.5", "--max-area", "0.2", "--occlusion"]);
        rate_options(&a, &mut o, 1.0);
        assert_eq!((o.min_area, o.max_area, o.occlusion), (0.5, 0.5, true));
        // A family's minimum tilt (the tilt family's 30°) stays unless --min-tilt is given.
        let mut t = SceneOptions {
            min_tilt_deg: 30.0,
            max_tilt_deg: 50.0,
            ..SceneOptions::default()
        };
        rate_options(&args(&[]), &mut t, 1.0);
        assert_eq!((t.min_tilt_deg, t.max_tilt_deg), (30.0, 50.0));
        rate_options(&args(&["--min-tilt", "40"]), &mut t, 1.0);
        assert_eq!((t.min_tilt_deg, t.max_tilt_deg), (40.0, 50.0));
    }

    #[test]
    fn rate_arguments_outside_their_ranges_are_usage_errors() {
        assert!(check_rate_args(&args(&[])).is_ok());
        for bad in [
            &["--scenes", "0"][..],
            &["--seed", "18446744073709551615", "--scenes", "2"],
            &["--min-tilt", "40", "--max-tilt", "20"],
        ] {
            let e = check_rate_args(&args(bad)).unwrap_err();
            assert!(e.downcast_ref::<UsageError>().is_some(), "{bad:?}: {e}");
        }
        // Every family parses by its name; another name is refused, naming the known ones.
        for f in Family::ALL {
            assert_eq!(parse_family(f.name()), Ok(f));
        }
        let e = parse_family("spyder48").unwrap_err();
        assert!(e.contains("spyder24") && e.contains("nested"), "{e}");
        assert!(Rate::try_parse_from(["rate", "--family", "spyder48"]).is_err());
        // The negatives come in either chart's layout.
        for f in Family::ALL
            .into_iter()
            .filter(|f| f.negative())
            .map(Family::name)
        {
            assert!(check_rate_args(&args(&["--family", f])).is_ok());
            let sg = ["rate", "--chart", "sg", "--family", f];
            assert!(check_rate_args(&Rate::try_parse_from(sg).unwrap().a).is_ok());
        }
    }

    #[test]
    fn a_patch_is_misplaced_by_its_label_or_a_quarter_pitch() {
        let reading = |label: &str, centre: [f64; 2]| PatchReading {
            label: label.into(),
            rgb: [0.0; 3],
            std: [0.0; 3],
            count: 1,
            flags: Vec::new(),
            xyz: [0.0; 3],
            centre,
            outline: [[0.0; 2]; 4],
            flat: 1.0,
        };
        let truth = |label: &str, centre: [f64; 2]| TruePatch {
            label: label.into(),
            rgb: [0.0; 3],
            rgb_lit: [0.0; 3],
            xyz: [0.0; 3],
            centre,
            occluded: false,
            clipped: false,
        };
        let t = [truth("a", [0.0, 0.0]), truth("b", [10.0, 0.0])];
        let good = [reading("a", [2.0, 0.0]), reading("b", [10.0, 2.4])];
        let (bad, worst) = misplaced(&good, &t, 10.0);
        assert_eq!(bad, 0);
        assert!((worst - 0.24).abs() < 1e-12, "{worst}");
        let far = [reading("a", [3.0, 0.0]), reading("b", [10.0, 0.0])];
        assert_eq!(misplaced(&far, &t, 10.0), (1, 0.3));
        let swapped = [reading("b", [0.0, 0.0]), reading("a", [10.0, 0.0])];
        assert_eq!(misplaced(&swapped, &t, 10.0).0, 2);
    }
}
