//! `nsrm farm`: batches on farm engines.
//!
//! - `nsrm farm openjd|slurm|k8s --shards N --job-dir DIR [apply's options] INPUT… -o OUT`
//!   writes a ready job for the engine (see `crate::farmlib::jobs`).
//! - `nsrm farm run --shard K/N [--inputs-from FILE] [--path-map FROM=TO]… -- [apply's
//!   options] [INPUT…]` is one task: it keeps the shard's finished outputs (checked against
//!   its manifest, or read in full), removes stale temporaries of its own outputs, converts
//!   the rest with `apply`, and writes the shard's manifest beside the outputs.
//! - `nsrm farm verify OUT` checks the batch is whole (exit 1 naming what is not).

use super::apply;
use super::common::UsageError;
use crate::farmlib::jobs::{self, Arg, JobFile, JobSpec};
use crate::farmlib::manifest::{self, Batch, Entry, Failure, How, ModelRecord, ShardManifest};
use crate::farmlib::pathmap::PathMap;
use crate::farmlib::resources as farm_resources;
use crate::farmlib::verify::{self, Expect};
use anyhow::{Context, Result};
use clap::Parser;
use nsrm_io::batch::{self, Shard};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

#[derive(Debug, clap::Subcommand)]
pub(crate) enum Command {
    /// Write an Open Job Description job bundle (template.yaml, parameter_values.yaml,
    /// asset_references.yaml, inputs.txt; job_parameters.json for `openjd run`): the format AWS
    /// Deadline Cloud submits (job attachments upload the inputs); `openjd run` runs it locally.
    Openjd(GenArgs),
    /// Write a Slurm array job (array.sbatch, verify.sbatch, submit.sh).
    Slurm(GenArgs),
    /// Write a Kubernetes Indexed Job (job.yaml: the input list as a ConfigMap and the Job;
    /// verify.yaml: the verification, to apply once the Job has completed).
    K8s(KubeArgs),
    /// Run one shard as a farm task: keep its finished outputs, convert the rest, write its
    /// manifest.
    Run(RunArgs),
    /// Check that a batch is whole: every shard's manifest, every output there with the hash
    /// recorded, one model, no temporaries. Exit status 1 naming what is missing or wrong.
    Verify(VerifyArgs),
}

#[derive(Debug, clap::Args)]
pub(crate) struct GenArgs {
    /// Shards the batch is split into (one farm task each).
    #[arg(long, value_name = "N")]
    shards: usize,
    /// Where the job's files are written (created if missing); with --overwrite, files of the
    /// same names there are replaced.
    #[arg(long, value_name = "DIR")]
    job_dir: PathBuf,
    /// The job's name (letters, digits, -, _, .); by default `nsrm-` and 12 hex digits of a
    /// hash of the batch (inputs, model, output directory, shards, settings): two batches never
    /// share a name, and making the same batch again gives the same one.
    #[arg(long)]
    name: Option<String>,
    /// The nsrm program on the workers.
    #[arg(long, value_name = "PATH", default_value = "nsrm")]
    program: String,
    /// Rewrite paths under FROM (as named here) to TO (as the workers mount it); repeatable,
    /// the longest FROM wins. Slurm and Kubernetes only: an Open Job Description worker maps
    /// paths with its own path-mapping rules.
    #[arg(long = "path-map", value_name = "FROM=TO")]
    path_map: Vec<String>,
    /// apply's options and inputs (-o is required; --overwrite replaces the job's files).
    #[command(flatten)]
    apply: apply::Args,
    #[command(flatten)]
    resources: crate::farmlib::resources::ResourceArgs,
}

#[derive(Debug, clap::Args)]
pub(crate) struct KubeArgs {
    /// Container image with nsrm (and /bin/sh).
    #[arg(long, value_name = "IMAGE")]
    image: String,
    /// PersistentVolumeClaim holding the inputs, the model and the outputs.
    #[arg(long, value_name = "NAME")]
    claim: String,
    /// Where the claim is mounted in the pods (map paths onto it with --path-map).
    #[arg(long, value_name = "DIR", default_value = "/data")]
    mount: String,
    /// Pods running at once.
    #[arg(long, value_name = "P", default_value_t = 4)]
    parallelism: usize,
    /// Retries of one shard before it counts as failed (backoffLimitPerIndex).
    #[arg(long, value_name = "N", default_value_t = 3)]
    retries: usize,
    #[command(flatten)]
    gen: GenArgs,
}

#[derive(Debug, clap::Args)]
pub(crate) struct RunArgs {
    /// This task's shard: K of N (K from 1).
    #[arg(long, value_name = "K/N")]
    shard: String,
    /// A file listing the batch's inputs, one per line (`-`: standard input), added to the
    /// inputs given after `--`.
    #[arg(long, value_name = "FILE")]
    inputs_from: Option<PathBuf>,
    /// Rewrite listed inputs and the preview directory under FROM to TO; repeatable.
    #[arg(long = "path-map", value_name = "FROM=TO")]
    path_map: Vec<String>,
    /// An Open Job Description path-mapping rules file (a session's PathMappingRulesFile),
    /// applied like --path-map.
    #[arg(long, value_name = "FILE")]
    path_mapping_rules: Option<PathBuf>,
    /// The batch's name, for the task log's header (the generated jobs pass it).
    #[arg(long, value_name = "NAME")]
    batch: Option<String>,
    /// apply's options and inputs (-o is required).
    #[arg(last = true, value_name = "APPLY_ARGS")]
    apply: Vec<std::ffi::OsString>,
}

#[derive(Debug, clap::Args)]
pub(crate) struct VerifyArgs {
    /// The batch's output directory.
    #[arg(value_name = "DIR")]
    dir: PathBuf,
    /// Shards the job was made with (default: as the manifests say).
    #[arg(long, value_name = "N")]
    shards: Option<usize>,
    /// The model the job applies: every shard must have applied this file.
    #[arg(long, value_name = "FILE")]
    model: Option<PathBuf>,
    /// The job's preview directory: previews the manifests record are checked there (the
    /// directory a manifest records is not trusted).
    #[arg(long, value_name = "DIR")]
    preview: Option<PathBuf>,
    /// An Open Job Description path-mapping rules file applied to --preview.
    #[arg(long, value_name = "FILE")]
    path_mapping_rules: Option<PathBuf>,
}

/// `apply`'s arguments parsed on their own.
#[derive(Parser)]
#[command(name = "nsrm farm run --")]
struct ApplyCmd {
    #[command(flatten)]
    a: apply::Args,
}

pub(crate) fn run(c: Command) -> Result<ExitCode> {
    match c {
        Command::Openjd(g) => generate(Engine::Openjd, g),
        Command::Slurm(g) => generate(Engine::Slurm, g),
        Command::K8s(k) => {
            let kube = jobs::Kube {
                image: k.image,
                claim: k.claim,
                mount_path: k.mount,
                parallelism: k.parallelism,
                retries_per_index: k.retries,
            };
            generate(Engine::Kube(kube), k.gen)
        }
        Command::Run(r) => run_shard(r),
        Command::Verify(v) => run_verify(v),
    }
}

enum Engine {
    Openjd,
    Slurm,
    Kube(jobs::Kube),
}

impl Engine {
    fn name(&self) -> &'static str {
        match self {
            Engine::Openjd => "openjd",
            Engine::Slurm => "slurm",
            Engine::Kube(_) => "k8s",
        }
    }
}

fn utf8(p: &Path, what: &str) -> Result<String> {
    p.to_str().map(str::to_string).ok_or_else(|| {
        UsageError(format!(
            "{what} {}: a farm job lists paths as text; this one is not UTF-8",
            p.display()
        ))
        .into()
    })
}

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("{}", p.display()))
}

fn generate(engine: Engine, mut g: GenArgs) -> Result<ExitCode> {
    if g.shards == 0 || g.shards > crate::farmlib::MAX_SHARDS {
        return Err(UsageError(format!(
            "--shards {}: a batch has 1 to {} shards",
            g.shards,
            crate::farmlib::MAX_SHARDS
        ))
        .into());
    }
    let mut map = PathMap::new();
    for spec in &g.path_map {
        map.add_pair(spec).context("--path-map")?;
    }
    if matches!(engine, Engine::Openjd) && !map.is_empty() {
        return Err(UsageError(
            "--path-map is for Slurm and Kubernetes jobs; an Open Job Description worker maps \
             paths with its own path-mapping rules (openjd run --path-mapping-rules, or the \
             farm's storage profiles)"
                .into(),
        )
        .into());
    }
    if let Some(flag) = g.resources.foreign(engine.name()).first() {
        return Err(UsageError(format!(
            "{flag} is not for `nsrm farm {}` (see --help: each engine's flags)",
            engine.name()
        ))
        .into());
    }
    let mut settings = g.apply.settings_argv();
    let parts = g.apply.farm_parts();
    if let Some(flag) = parts.policy_flag {
        return Err(UsageError(format!(
            "{flag} is decided by each farm task (a retried task keeps its finished outputs); leave it out"
        ))
        .into());
    }
    let overwrite = parts.overwrite;
    let out = parts
        .output_dir
        .clone()
        .ok_or_else(|| UsageError("-o (the batch's output directory) is required".into()))?;
    let m = |p: &Path, what: &str| -> Result<String> { Ok(map.map(&utf8(&absolute(p)?, what)?)) };
    let model = m(parts.model, "--model")?;
    let output_dir = m(&out, "-o")?;
    let preview = parts
        .preview
        .as_deref()
        .map(|p| m(p, "--preview"))
        .transpose()?;
    let found = batch::expand_inputs(parts.inputs)?;
    let mut inputs = Vec::with_capacity(found.len());
    for i in &found {
        inputs.push(m(i, "input")?);
    }
    let resources = farm_resources::resolve(&g.resources, &mut settings, &found)?;

    let mut task = task_args(
        matches!(engine, Engine::Openjd),
        preview.as_deref(),
        &settings,
    );
    let verify = verify_args(matches!(engine, Engine::Openjd), preview.as_deref());
    let batch_id = batch_name(&inputs, &model, &output_dir, g.shards, &settings);
    let name = match &g.name {
        Some(n) => n.clone(),
        None => {
            eprintln!("nsrm farm: job name {batch_id} (from the batch; --name sets another)");
            batch_id.clone()
        }
    };
    task.splice(2..2, [Arg::Lit("--batch".into()), Arg::Lit(name.clone())]);
    if let Engine::Kube(k) = &engine {
        let mut paths = vec![model.as_str(), output_dir.as_str()];
        paths.extend(preview.as_deref());
        paths.extend(inputs.iter().map(String::as_str));
        if let Some(w) = farm_resources::outside_mount(&k.mount_path, &paths) {
            eprintln!("{w}");
        }
    }
    let spec = JobSpec {
        name,
        shards: g.shards,
        inputs,
        model,
        output_dir,
        preview_dir: preview.clone(),
        job_dir: m(&g.job_dir, "--job-dir")?,
        program: g.program.clone(),
        task,
        verify,
        resources,
        batch: batch_id,
    };
    let (files, how) = engine_files(&engine, &spec, &g.job_dir)?;
    write_job(&g.job_dir, &files, overwrite)?;
    eprintln!(
        "nsrm farm: {} input(s) in {} shard(s); wrote {} in {}",
        spec.inputs.len(),
        spec.shards,
        files
            .iter()
            .map(|f| f.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        g.job_dir.display()
    );
    eprintln!("nsrm farm: run it with: {how}");
    Ok(ExitCode::SUCCESS)
}

/// The default job name of a batch: `nsrm-` and the first 12 hex digits of the SHA-256 of its
/// inputs, model, output directory, shard count and settings (each field's length first, so no
/// two different batches join to the same text).
fn batch_name(
    inputs: &[String],
    model: &str,
    output_dir: &str,
    shards: usize,
    settings: &[String],
) -> String {
    let mut text = String::new();
    let shards = shards.to_string();
    let fields = inputs
        .iter()
        .map(String::as_str)
        .chain(["", model, output_dir, &shards, ""])
        .chain(settings.iter().map(String::as_str));
    for f in fields {
        text.push_str(&format!("{}:{f};", f.len()));
    }
    format!(
        "nsrm-{}",
        &crate::farmlib::sha256_bytes(text.as_bytes())[..12]
    )
}

/// A shard's command after the program: `farm run` of the shard with the listed inputs (and,
/// for Open Job Description, its path-mapping rules), then the apply flags: the model, the
/// output directory, the `preview` directory and the conversion `settings`.
fn task_args(openjd: bool, preview: Option<&str>, settings: &[String]) -> Vec<Arg> {
    let lit = |s: &str| Arg::Lit(s.to_string());
    let mut task = vec![
        lit("farm"),
        lit("run"),
        lit("--shard"),
        Arg::Shard,
        lit("--inputs-from"),
        Arg::InputList,
    ];
    if openjd {
        task.extend([lit("--path-mapping-rules"), Arg::PathMappingRules]);
    }
    task.extend([
        lit("--"),
        lit("--model"),
        Arg::Model,
        lit("-o"),
        Arg::OutputDir,
    ]);
    if let Some(p) = preview {
        task.extend([lit("--preview"), lit(p)]);
    }
    task.extend(settings.iter().map(|s| lit(s)));
    task
}

/// The verification's command after the program: `farm verify` of the output directory with
/// the shard count, the model and the `preview` directory (for Open Job Description, mapped by
/// the session's path-mapping rules).
fn verify_args(openjd: bool, preview: Option<&str>) -> Vec<Arg> {
    let lit = |s: &str| Arg::Lit(s.to_string());
    let mut v = vec![
        lit("farm"),
        lit("verify"),
        Arg::OutputDir,
        lit("--shards"),
        Arg::Shards,
        lit("--model"),
        Arg::Model,
    ];
    if let Some(p) = preview {
        v.extend([lit("--preview"), lit(p)]);
        if openjd {
            v.extend([lit("--path-mapping-rules"), Arg::PathMappingRules]);
        }
    }
    v
}

/// The engine's job files for `spec`, and how to run them from `job_dir`.
fn engine_files(engine: &Engine, spec: &JobSpec, job_dir: &Path) -> Result<(Vec<JobFile>, String)> {
    Ok(match engine {
        Engine::Openjd => (
            jobs::openjd(spec)?,
            format!(
                "openjd run {dir}/template.yaml --step Apply -p file://{dir}/job_parameters.json, then --step Verify; or submit {dir} as a Deadline Cloud job bundle",
                dir = job_dir.display()
            ),
        ),
        Engine::Slurm => (
            jobs::slurm(spec)?,
            format!("sh {}/submit.sh", job_dir.display()),
        ),
        Engine::Kube(k) => (
            jobs::kube(spec, k)?,
            format!(
                "kubectl apply -f {dir}/job.yaml && sh {dir}/wait.sh && kubectl apply -f {dir}/verify.yaml (wait.sh returns when job/{name} is Complete or Failed, and says which)",
                dir = job_dir.display(),
                name = spec.name
            ),
        ),
    })
}

/// Writes the job's files together: all staged, then committed (all appear or none).
fn write_job(dir: &Path, files: &[JobFile], overwrite: bool) -> Result<()> {
    let dests: Vec<PathBuf> = files.iter().map(|f| dir.join(&f.name)).collect();
    let dests: Vec<&Path> = dests.iter().map(PathBuf::as_path).collect();
    let session = super::outputs::open(overwrite, &[], &dests)?;
    let mut unit = session.unit();
    for f in files {
        unit.write_bytes(&dir.join(&f.name), f.text.as_bytes())?;
    }
    unit.commit()?;
    #[cfg(unix)]
    for f in files.iter().filter(|f| f.executable) {
        use std::os::unix::fs::PermissionsExt;
        let dest = dir.join(&f.name);
        std::fs::set_permissions(&dest, std::fs::Permissions::from_mode(0o755))
            .with_context(|| format!("making {} executable", dest.display()))?;
    }
    Ok(())
}

/// Reads an input list: one path per line, blank lines ignored.
fn read_list(path: &Path) -> Result<Vec<String>> {
    const LIMIT: u64 = crate::farmlib::MAX_RECORD_BYTES;
    let bytes = if path == Path::new("-") {
        use std::io::Read;
        let mut v = Vec::new();
        std::io::stdin()
            .take(LIMIT + 1)
            .read_to_end(&mut v)
            .context("reading the input list from standard input")?;
        if v.len() as u64 > LIMIT {
            anyhow::bail!("the input list on standard input is over {LIMIT} bytes");
        }
        v
    } else {
        crate::farmlib::read_bounded(path, LIMIT).context("--inputs-from")?
    };
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow::anyhow!("{}: the input list is not UTF-8", path.display()))?;
    Ok(text
        .lines()
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .filter(|l| !l.trim().is_empty())
        .map(str::to_string)
        .collect())
}

fn secs(t: Instant) -> f64 {
    (t.elapsed().as_secs_f64() * 1e3).round() / 1e3
}

/// What a farm task found for one of its outputs before converting.
enum Found {
    /// Finished: kept as it is.
    Done(Entry),
    /// To convert (`true`: something broken or stale is there and is replaced).
    Todo(bool),
}

fn run_shard(r: RunArgs) -> Result<ExitCode> {
    let t0 = Instant::now();
    let started_unix = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0);
    let shard = Shard::parse(&r.shard).context("--shard")?;
    if shard.count > crate::farmlib::MAX_SHARDS {
        return Err(UsageError(format!(
            "--shard {shard}: a batch has at most {} shards",
            crate::farmlib::MAX_SHARDS
        ))
        .into());
    }
    let mut a = shard_apply_args(&r)?;
    let parts = a.farm_parts();
    let out_dir = parts
        .output_dir
        .clone()
        .ok_or_else(|| UsageError("-o (the batch's output directory) is required".into()))?;
    let model_path = parts.model.clone();
    let inputs = batch::expand_inputs(parts.inputs)?;
    let settings = a.settings_argv();
    let (_, model_sha) = crate::farmlib::sha256_file(&model_path).context("--model")?;
    let plan = a
        .farm_plan(&inputs, shard)
        .context("planning the outputs (--suffix, -o, --preview)")?;
    // Every output's name in the batch (all shards), for the batch's identity.
    let all_names: Vec<String> = {
        let full = a
            .farm_plan(&inputs, Shard { index: 1, count: 1 })
            .context("planning the outputs")?;
        full.jobs
            .iter()
            .map(|j| name_of(&j.output))
            .collect::<Result<_>>()?
    };
    log_header(&r, shard, &settings, plan.jobs.len(), all_names.len());
    let batch_id = Batch::of(&all_names);
    let previous =
        ShardManifest::read(&out_dir.join(manifest::file_name(shard.index, shard.count)))
            .ok()
            .filter(|m| m.batch == batch_id);
    let same_run = previous
        .as_ref()
        .is_some_and(|m| m.model.sha256 == model_sha && m.settings == settings);
    let removed = remove_stale_temporaries(&plan, &super::outputs::stale_temporaries(&plan));

    // What is finished already.
    let read_opts = a.farm_read_options();
    let mut found = Vec::with_capacity(plan.jobs.len());
    for j in &plan.jobs {
        found.push(check_existing(j, previous.as_ref(), same_run, &read_opts)?);
    }
    let check_s = secs(t0);

    // Convert the rest.
    let todo: Vec<&batch::Job> = plan
        .jobs
        .iter()
        .zip(&found)
        .filter(|(_, f)| matches!(f, Found::Todo(_)))
        .map(|(j, _)| j)
        .collect();
    let replace = found.iter().any(|f| matches!(f, Found::Todo(true)));
    eprintln!(
        "nsrm farm run: {} finished already (kept or adopted), {} to convert ({:.2} s checking)",
        found.len() - todo.len(),
        todo.len(),
        check_s
    );
    let t1 = Instant::now();
    let mut status = ExitCode::SUCCESS;
    if !todo.is_empty() {
        let inputs = todo.iter().map(|j| j.input.clone()).collect();
        status = a.farm_convert(inputs, replace)?;
    }
    let convert_s = secs(t1);

    // Record.
    let t2 = Instant::now();
    let (outputs, failures) = record(&plan.jobs, found);
    let m = ShardManifest {
        format: manifest::FORMAT.into(),
        nsrm_version: env!("CARGO_PKG_VERSION").into(),
        shard: shard.index,
        shards: shard.count,
        batch: batch_id,
        model: ModelRecord {
            path: model_path.display().to_string(),
            sha256: model_sha,
        },
        settings,
        outputs,
        failures,
        stale_temporaries_removed: removed,
        timings: manifest::Timings {
            started_unix,
            check_s,
            convert_s,
            hash_s: secs(t2),
            total_s: secs(t0),
        },
    };
    let path = m
        .write(&out_dir, &nsrm_output::Session::new(true))
        .context("writing the shard manifest")?;
    eprintln!("{}", shard_summary(shard, &m, &path));
    if !m.failures.is_empty() && status == ExitCode::SUCCESS {
        status = ExitCode::from(1);
    }
    Ok(status)
}

/// The task log's header: nsrm, the batch, the shard, the host, the frames, the device asked.
fn log_header(r: &RunArgs, shard: Shard, settings: &[String], frames: usize, batch_frames: usize) {
    let host = crate::farmlib::tasklog::host_name();
    let header = crate::farmlib::tasklog::Header {
        batch: r.batch.as_deref(),
        shard: (shard.index, shard.count),
        host: &host,
        settings,
        frames,
        batch_frames,
    };
    for line in header.lines() {
        eprintln!("{line}");
    }
}

/// The apply arguments of a farm task: those after its `--`, its input list's lines (both
/// through its path mapping), checked for the flags the task decides itself; it continues
/// past a bad file.
fn shard_apply_args(r: &RunArgs) -> Result<apply::Args> {
    let mut map = PathMap::new();
    for spec in &r.path_map {
        map.add_pair(spec).context("--path-map")?;
    }
    if let Some(f) = &r.path_mapping_rules {
        map.add_openjd_file(f).context("--path-mapping-rules")?;
    }
    let mut argv: Vec<std::ffi::OsString> = vec!["nsrm farm run --".into()];
    argv.extend(r.apply.iter().cloned());
    if let Some(list) = &r.inputs_from {
        if !r.apply.iter().any(|a| a == "--") {
            argv.push("--".into());
        }
        argv.extend(read_list(list)?.iter().map(|l| map.map(l).into()));
    }
    let mut a = ApplyCmd::try_parse_from(&argv)
        .map_err(|e| UsageError(format!("apply's arguments after --: {e}")))?
        .a;
    let parts = a.farm_parts();
    if let Some(flag) = parts
        .policy_flag
        .or(parts.overwrite.then_some("--overwrite"))
    {
        return Err(UsageError(format!(
            "{flag} is decided by the farm task itself (it keeps finished outputs and replaces broken ones); leave it out"
        ))
        .into());
    }
    *parts.continue_on_error = true;
    if let Some(p) = parts.preview.as_mut() {
        *p = PathBuf::from(map.map(&utf8(p, "--preview")?));
    }
    Ok(a)
}

/// Removes the stale temporaries (a killed run's) of this shard's own outputs and previews
/// (none of another shard's); their names.
fn remove_stale_temporaries(plan: &batch::BatchPlan, stale: &[PathBuf]) -> Vec<String> {
    let mine: Vec<String> = plan
        .jobs
        .iter()
        .flat_map(|j| [Some(&j.output), j.preview.as_ref()])
        .flatten()
        .filter_map(|p| p.file_name().map(|n| format!(".{}.", n.to_string_lossy())))
        .collect();
    let mut removed = Vec::new();
    for t in stale {
        let name = t.file_name().map(|n| n.to_string_lossy().into_owned());
        if let Some(name) = name.filter(|n| mine.iter().any(|m| n.starts_with(m.as_str()))) {
            match std::fs::remove_file(t) {
                Ok(()) => removed.push(name),
                Err(e) => eprintln!("nsrm farm run: cannot remove {}: {e}", t.display()),
            }
        }
    }
    removed
}

/// The manifest's records of the shard's jobs after the conversion: what was kept, and for
/// each converted output its record or, when it is missing or unreadable, a failure.
fn record(jobs: &[batch::Job], found: Vec<Found>) -> (Vec<Entry>, Vec<Failure>) {
    let mut outputs = Vec::new();
    let mut failures = Vec::new();
    for (j, f) in jobs.iter().zip(found) {
        match f {
            Found::Done(e) => outputs.push(e),
            Found::Todo(replaced) => {
                let how = if replaced {
                    How::Replaced
                } else {
                    How::Converted
                };
                match entry(j, how) {
                    Ok(e) => outputs.push(e),
                    Err(why) => failures.push(Failure {
                        input: j.input.display().to_string(),
                        output: name_of(&j.output).unwrap_or_default(),
                        why,
                    }),
                }
            }
        }
    }
    (outputs, failures)
}

/// The task's one-line summary of its manifest `m` (written at `path`).
fn shard_summary(shard: Shard, m: &ShardManifest, path: &Path) -> String {
    let count = |h: How| m.outputs.iter().filter(|e| e.how == h).count();
    let n_removed = m.stale_temporaries_removed.len();
    format!(
        "nsrm farm run: shard {shard}: {} converted, {} replaced, {} kept, {} adopted (complete, found without a record), {} failed; {} stale temporar{} removed; {:.2} s; manifest {}",
        count(How::Converted),
        count(How::Replaced),
        count(How::Kept),
        count(How::Adopted),
        m.failures.len(),
        n_removed,
        if n_removed == 1 { "y" } else { "ies" },
        m.timings.total_s,
        path.display()
    )
}

fn name_of(p: &Path) -> Result<String> {
    p.file_name()
        .and_then(|n| n.to_str())
        .map(str::to_string)
        .ok_or_else(|| anyhow::anyhow!("{}: the output's name is not UTF-8", p.display()))
}

/// The record of a finished output (hashes the output and its preview).
fn entry(j: &batch::Job, how: How) -> std::result::Result<Entry, String> {
    if !j.output.is_file() {
        return Err("no output after the conversion (see the task's log)".into());
    }
    let (bytes, sha256) = crate::farmlib::sha256_file(&j.output).map_err(|e| e.to_string())?;
    let preview = match &j.preview {
        None => None,
        Some(p) => {
            let (bytes, sha256) = crate::farmlib::sha256_file(p).map_err(|e| e.to_string())?;
            Some(manifest::Preview {
                path: p.display().to_string(),
                bytes,
                sha256,
            })
        }
    };
    Ok(Entry {
        input: j.input.display().to_string(),
        output: name_of(&j.output).map_err(|e| e.to_string())?,
        bytes,
        sha256,
        preview,
        how,
    })
}

/// Whether `j`'s output is finished: recorded by an earlier run of this shard with the same
/// model and settings and unchanged since (size and hash), or, with no record, complete (read
/// in full). Anything else there is broken or stale and is converted again.
fn check_existing(
    j: &batch::Job,
    previous: Option<&ShardManifest>,
    same_run: bool,
    read: &nsrm_io::ReadOptions,
) -> Result<Found> {
    let there = j.output.is_file() && j.preview.as_ref().is_none_or(|p| p.is_file());
    if !j.output.exists() && j.preview.as_ref().is_none_or(|p| !p.exists()) {
        return Ok(Found::Todo(false));
    }
    if !there {
        return Ok(Found::Todo(true));
    }
    let name = name_of(&j.output)?;
    let record = previous.and_then(|m| m.outputs.iter().find(|e| e.output == name));
    match (record, same_run) {
        (Some(rec), true) => Ok(match entry(j, How::Kept) {
            Ok(e)
                if e.bytes == rec.bytes
                    && e.sha256 == rec.sha256
                    && e.preview.as_ref().map(|p| &p.sha256)
                        == rec.preview.as_ref().map(|p| &p.sha256) =>
            {
                Found::Done(e)
            }
            _ => Found::Todo(true),
        }),
        // Recorded by a run of another model or settings: stale.
        (Some(_), false) => Ok(Found::Todo(true)),
        (None, _) if previous.is_some() && !same_run => Ok(Found::Todo(true)),
        (None, _) => {
            let complete = nsrm_io::Decoded::read(&j.output, read).is_ok();
            Ok(if complete {
                match entry(j, How::Adopted) {
                    Ok(e) => Found::Done(e),
                    Err(_) => Found::Todo(true),
                }
            } else {
                Found::Todo(true)
            })
        }
    }
}

/// `farm verify`'s preview directory, through its path-mapping rules.
fn verify_preview_dir(v: &VerifyArgs) -> Result<Option<PathBuf>> {
    let Some(p) = &v.preview else {
        return Ok(None);
    };
    let mut map = PathMap::new();
    if let Some(f) = &v.path_mapping_rules {
        map.add_openjd_file(f).context("--path-mapping-rules")?;
    }
    Ok(Some(PathBuf::from(map.map(&utf8(p, "--preview")?))))
}

fn run_verify(v: VerifyArgs) -> Result<ExitCode> {
    let model_sha256 = match &v.model {
        Some(p) => Some(crate::farmlib::sha256_file(p).context("--model")?.1),
        None => None,
    };
    if let Some(n) = v
        .shards
        .filter(|&n| n == 0 || n > crate::farmlib::MAX_SHARDS)
    {
        return Err(UsageError(format!(
            "--shards {n}: a batch has 1 to {} shards",
            crate::farmlib::MAX_SHARDS
        ))
        .into());
    }
    let t = Instant::now();
    let r = verify::verify(
        &v.dir,
        &Expect {
            shards: v.shards,
            model_sha256,
            preview_dir: verify_preview_dir(&v)?,
        },
    )?;
    let summary = format!(
        "{} manifest(s) of {} shard(s), {} input(s); {} output(s) match their hashes ({:.1} MB hashed in {:.2} s)",
        r.manifests,
        r.shards,
        r.inputs,
        r.outputs_ok,
        r.bytes as f64 / 1e6,
        t.elapsed().as_secs_f64()
    );
    if r.ok() {
        println!("nsrm farm verify: OK: {}: {summary}", v.dir.display());
        return Ok(ExitCode::SUCCESS);
    }
    eprintln!(
        "nsrm farm verify: FAILED: {}: {} problem(s); {summary}",
        v.dir.display(),
        r.problems.len()
    );
    for p in &r.problems {
        eprintln!("  {p}");
    }
    if v.preview.is_none() && r.problems.iter().any(|p| p.contains("preview directory")) {
        eprintln!("nsrm farm verify: the previews are checked with --preview DIR (the job's)");
    }
    Ok(ExitCode::from(1))
}

#[cfg(test)]
#[path = "farm_tests.rs"]
mod tests;
