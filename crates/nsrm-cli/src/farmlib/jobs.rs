//! Job descriptions in the engines' own formats: an Open Job Description template (the format
//! AWS Deadline Cloud submits, laid out as a job bundle), a Slurm array script with a dependent
//! verification job, and a Kubernetes Indexed Job.
//!
//! The caller gives the command a worker runs for a shard and for the verification as a list of
//! [`Arg`]s: literal words and the places where each engine puts its own values (the shard, the
//! input list, the model, the output directory). Every file is generated text; nothing here
//! runs anything.

use super::yaml;
use super::FarmError;
use serde::Serialize;

/// One word of a worker's command line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Arg {
    /// Passed as it is.
    Lit(String),
    /// `K/N`: this task's shard (1-based) and the shard count.
    Shard,
    /// The shard count.
    Shards,
    /// A file listing the batch's inputs, one per line (on Slurm, standard input: `-`).
    InputList,
    /// A file of Open Job Description path-mapping rules (Open Job Description only).
    PathMappingRules,
    /// The model file.
    Model,
    /// The output directory.
    OutputDir,
}

/// A batch to describe as a job.
#[derive(Debug, Clone)]
pub(crate) struct JobSpec {
    /// The job's name (letters, digits, `-`, `_`, `.`).
    pub name: String,
    pub shards: usize,
    /// The inputs, one file each, as the workers (or, for Open Job Description, the submitter)
    /// name them.
    pub inputs: Vec<String>,
    pub model: String,
    pub output_dir: String,
    /// The previews' directory, when the job writes previews (an output of the job).
    pub preview_dir: Option<String>,
    /// The job's directory as the submitter names it (an Open Job Description bundle's input
    /// list is a file there, given to the workers as a `PATH` parameter).
    pub job_dir: String,
    /// The nsrm program on the workers.
    pub program: String,
    /// The command of one shard, after the program.
    pub task: Vec<Arg>,
    /// The verification's command, after the program.
    pub verify: Vec<Arg>,
    /// What each task asks the engine for.
    pub resources: super::resources::Resources,
    /// The batch's own name (`nsrm-` and 12 hex digits of its hash), a label of its
    /// Kubernetes objects whatever the job's name.
    pub batch: String,
}

/// A generated file: its name in the job's directory, its text, and whether it is executable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct JobFile {
    pub name: String,
    pub text: String,
    pub executable: bool,
}

impl JobSpec {
    /// Refuses what no job format can carry: no shards, no inputs, a line break or NUL in a path
    /// (the input list is one path per line), a name that is not a plain word.
    pub(crate) fn check(&self) -> Result<(), FarmError> {
        let usage = |s: String| Err(FarmError::Usage(s));
        if self.shards == 0 {
            return usage("the shard count must be at least 1".into());
        }
        if self.inputs.is_empty() {
            return usage("the batch has no inputs".into());
        }
        if self.name.is_empty()
            || self.name.len() > 50
            || !self
                .name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
        {
            return usage(format!(
                "job name `{}`: use 1 to 50 letters, digits, `-`, `_` or `.`",
                self.name
            ));
        }
        for p in self
            .inputs
            .iter()
            .chain([&self.model, &self.output_dir, &self.program])
        {
            if p.contains(['\n', '\r', '\0']) {
                return usage(format!(
                    "{p:?}: a path with a line break cannot be listed in a job"
                ));
            }
        }
        Ok(())
    }

    fn input_list(&self) -> String {
        let mut s = String::new();
        for i in &self.inputs {
            s.push_str(i);
            s.push('\n');
        }
        s
    }
}

/// The file of an Open Job Description bundle listing the batch's inputs, one per line.
pub(crate) const OPENJD_INPUT_LIST: &str = "inputs.txt";

/// The job parameters' values as `openjd run --job-param file://…` reads them.
pub(crate) const OPENJD_RUN_VALUES: &str = "job_parameters.json";

/// The most characters of an Open Job Description `STRING` parameter's value.
const OPENJD_MAX_STRING: usize = 1024;

/// Whether `s` would be read as (part of) an Open Job Description expression in a format
/// string (`{{ … }}`); such a word reaches the worker as a parameter's value instead.
fn openjd_needs_param(s: &str) -> bool {
    s.contains("{{") || s.contains("}}")
}

/// The literal words of the job's commands that no format string can hold as they are, in
/// order, each once: they become `STRING` job parameters `NsrmArg1`, `NsrmArg2`, … whose
/// values (never parsed as templates) are the words.
fn openjd_literals(spec: &JobSpec) -> Result<Vec<String>, FarmError> {
    let mut out: Vec<String> = Vec::new();
    for a in spec.task.iter().chain(&spec.verify) {
        if let Arg::Lit(s) = a {
            if openjd_needs_param(s) && !out.contains(s) {
                if s.chars().count() > OPENJD_MAX_STRING {
                    return Err(FarmError::Usage(format!(
                        "{s:?}: a word holding `{{{{` or `}}}}` reaches an Open Job Description worker as a parameter, of at most {OPENJD_MAX_STRING} characters"
                    )));
                }
                out.push(s.clone());
            }
        }
    }
    Ok(out)
}

/// Open Job Description's text for one argument; a literal with `{{` or `}}` is the parameter
/// of `literals` holding it.
fn openjd_arg(a: &Arg, literals: &[String]) -> String {
    match a {
        Arg::Lit(s) => match literals.iter().position(|l| l == s) {
            Some(i) => format!("{{{{Param.NsrmArg{}}}}}", i + 1),
            None => s.clone(),
        },
        Arg::Shard => "{{Task.Param.Shard}}/{{Param.Shards}}".into(),
        Arg::Shards => "{{Param.Shards}}".into(),
        Arg::InputList => "{{Param.InputList}}".into(),
        Arg::PathMappingRules => "{{Session.PathMappingRulesFile}}".into(),
        Arg::Model => "{{Param.Model}}".into(),
        Arg::OutputDir => "{{Param.OutputDir}}".into(),
    }
}

/// An Open Job Description job bundle (`jobtemplate-2023-09`), ready for Deadline Cloud with or
/// without shared storage:
/// - `template.yaml`: job parameters `Shards` (INT), `InputList` and `Model` (PATH, FILE, IN),
///   `OutputDir` (PATH, DIRECTORY, OUT), `NsrmProgram` and one `NsrmArgK` per word no format
///   string can hold; a step `Apply` whose task parameter `Shard` ranges over
///   `1-{{Param.Shards}}`, a step `Verify` depending on it. No user text is ever part of a
///   format string: paths and such words are parameter values, which are not templates.
/// - `inputs.txt`: the batch's inputs, one per line, as the submitter names them (a worker maps
///   them with its session's path-mapping rules, the ones job attachments or storage profiles
///   give).
/// - `asset_references.yaml`: every input file (uploaded by job attachments) and the output
///   directories (downloaded).
/// - `parameter_values.yaml` in Deadline Cloud's job-bundle form, `parameter_values.json` for
///   `openjd run`'s job parameters.
pub(crate) fn openjd(spec: &JobSpec) -> Result<Vec<JobFile>, FarmError> {
    spec.check()?;
    let literals = openjd_literals(spec)?;
    let template = OpenjdTemplate {
        specification_version: "jobtemplate-2023-09",
        name: &spec.name,
        description: format!(
            "nsrm: {} input(s) in {} shard(s); each shard writes a manifest beside its outputs, the Verify step checks the batch is whole",
            spec.inputs.len(),
            spec.shards
        ),
        parameter_definitions: openjd_parameters(spec, &literals),
        steps: openjd_steps(spec, &literals),
    };
    let (bundle_values, json) = openjd_values(spec);
    let file = |name: &str, text: String| JobFile {
        name: name.into(),
        text,
        executable: false,
    };
    Ok(vec![
        file("template.yaml", to_yaml(&template)?),
        file("parameter_values.yaml", to_yaml(&bundle_values)?),
        file(OPENJD_RUN_VALUES, json),
        file(OPENJD_INPUT_LIST, spec.input_list()),
        file(
            "asset_references.yaml",
            to_yaml(&openjd_asset_references(spec))?,
        ),
    ])
}

/// A document's YAML text; a value the writer refuses is a request no job can carry.
fn to_yaml<T: Serialize>(doc: &T) -> Result<String, FarmError> {
    yaml::to_string(doc).map_err(|e| FarmError::Usage(e.to_string()))
}

/// An Open Job Description job template (`jobtemplate-2023-09`), as far as nsrm writes one.
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdTemplate<'a> {
    specification_version: &'static str,
    name: &'a str,
    description: String,
    parameter_definitions: Vec<OpenjdParameter<'a>>,
    steps: Vec<OpenjdStep<'a>>,
}

/// A job parameter's definition: `INT` (a default and minimum), `PATH` (an object type and
/// data flow) or `STRING` (a default).
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdParameter<'a> {
    name: String,
    #[serde(rename = "type")]
    ty: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    object_type: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    data_flow: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    default: Option<OpenjdDefault<'a>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    min_value: Option<usize>,
    description: &'static str,
}

/// A parameter's default value, of its type.
#[derive(Debug, PartialEq, Serialize)]
#[serde(untagged)]
enum OpenjdDefault<'a> {
    Int(usize),
    Str(&'a str),
}

/// A step: `Apply` with its task parameter, `Verify` with its dependency.
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdStep<'a> {
    name: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    parameter_space: Option<OpenjdParameterSpace>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    dependencies: Vec<OpenjdDependency>,
    #[serde(skip_serializing_if = "Option::is_none")]
    host_requirements: Option<super::resources::HostRequirements<'a>>,
    script: OpenjdScript,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdParameterSpace {
    task_parameter_definitions: Vec<OpenjdTaskParameter>,
}

#[derive(Debug, Serialize)]
struct OpenjdTaskParameter {
    name: &'static str,
    #[serde(rename = "type")]
    ty: &'static str,
    range: &'static str,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdDependency {
    depends_on: &'static str,
}

#[derive(Debug, Serialize)]
struct OpenjdScript {
    actions: OpenjdActions,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdActions {
    on_run: OpenjdAction,
}

/// The command a task runs, its arguments and its time limit in seconds.
#[derive(Debug, PartialEq, Serialize)]
struct OpenjdAction {
    command: &'static str,
    args: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    timeout: Option<u64>,
}

/// `asset_references.yaml` of a job bundle.
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdAssetReferences<'a> {
    asset_references: OpenjdAssets<'a>,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdAssets<'a> {
    inputs: OpenjdAssetInputs<'a>,
    outputs: OpenjdAssetOutputs<'a>,
    referenced_paths: Vec<&'a str>,
}

#[derive(Debug, Serialize)]
struct OpenjdAssetInputs<'a> {
    filenames: Vec<&'a str>,
    directories: Vec<&'a str>,
}

#[derive(Debug, Serialize)]
struct OpenjdAssetOutputs<'a> {
    directories: Vec<&'a str>,
}

/// `parameter_values.yaml` of a job bundle.
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct OpenjdParameterValues {
    parameter_values: Vec<OpenjdParameterValue>,
}

#[derive(Debug, Serialize)]
struct OpenjdParameterValue {
    name: &'static str,
    value: String,
}

/// `asset_references.yaml`: the inputs as files job attachments upload, the output (and
/// preview) directories as those they download.
fn openjd_asset_references(spec: &JobSpec) -> OpenjdAssetReferences<'_> {
    let mut outputs = vec![spec.output_dir.as_str()];
    outputs.extend(spec.preview_dir.as_deref());
    OpenjdAssetReferences {
        asset_references: OpenjdAssets {
            inputs: OpenjdAssetInputs {
                filenames: spec.inputs.iter().map(String::as_str).collect(),
                directories: Vec::new(),
            },
            outputs: OpenjdAssetOutputs {
                directories: outputs,
            },
            referenced_paths: Vec::new(),
        },
    }
}

/// The path of the bundle's input list as the submitter names it.
fn openjd_input_list_path(spec: &JobSpec) -> String {
    format!("{}/{OPENJD_INPUT_LIST}", spec.job_dir.trim_end_matches('/'))
}

/// The template's job parameters: `Shards` (INT), `InputList`, `Model` and `OutputDir` (PATH),
/// `NsrmProgram` and the `literals` (STRING).
fn openjd_parameters<'a>(spec: &'a JobSpec, literals: &'a [String]) -> Vec<OpenjdParameter<'a>> {
    let param = |name: &str, ty, default, description| OpenjdParameter {
        name: name.into(),
        ty,
        object_type: None,
        data_flow: None,
        default,
        min_value: None,
        description,
    };
    let path = |name, object, flow, description| OpenjdParameter {
        object_type: Some(object),
        data_flow: Some(flow),
        ..param(name, "PATH", None, description)
    };
    let mut params = vec![
        OpenjdParameter {
            min_value: Some(1),
            ..param(
                "Shards",
                "INT",
                Some(OpenjdDefault::Int(spec.shards)),
                "Shards the batch is split into (one task each)",
            )
        },
        path(
            "InputList",
            "FILE",
            "IN",
            "The batch's inputs, one path per line (inputs.txt of the bundle)",
        ),
        path("Model", "FILE", "IN", "The model file (nsrm fit)"),
        path(
            "OutputDir",
            "DIRECTORY",
            "OUT",
            "Where the outputs and the shard manifests go",
        ),
        param(
            "NsrmProgram",
            "STRING",
            Some(OpenjdDefault::Str(&spec.program)),
            "The nsrm program on the workers",
        ),
    ];
    for (i, l) in literals.iter().enumerate() {
        params.push(param(
            &format!("NsrmArg{}", i + 1),
            "STRING",
            Some(OpenjdDefault::Str(l)),
            "A word of nsrm's command line (a parameter, so that it is never read as a template)",
        ));
    }
    params
}

/// The action running `{{Param.NsrmProgram}}` with `list`'s arguments, stopped after
/// `timeout_s` seconds when given.
fn openjd_action(list: &[Arg], literals: &[String], timeout_s: Option<u64>) -> OpenjdScript {
    OpenjdScript {
        actions: OpenjdActions {
            on_run: OpenjdAction {
                command: "{{Param.NsrmProgram}}",
                args: list.iter().map(|a| openjd_arg(a, literals)).collect(),
                timeout: timeout_s,
            },
        },
    }
}

/// The template's steps: `Apply` (a task per shard) and `Verify` after it, each with its host
/// requirements.
fn openjd_steps<'a>(spec: &'a JobSpec, literals: &[String]) -> Vec<OpenjdStep<'a>> {
    let r = &spec.resources;
    vec![
        OpenjdStep {
            name: "Apply",
            parameter_space: Some(OpenjdParameterSpace {
                task_parameter_definitions: vec![OpenjdTaskParameter {
                    name: "Shard",
                    ty: "INT",
                    range: "1-{{Param.Shards}}",
                }],
            }),
            dependencies: Vec::new(),
            host_requirements: r.openjd_host_requirements(true),
            script: openjd_action(&spec.task, literals, r.time_s),
        },
        OpenjdStep {
            name: "Verify",
            parameter_space: None,
            dependencies: vec![OpenjdDependency {
                depends_on: "Apply",
            }],
            host_requirements: r.openjd_host_requirements(false),
            script: openjd_action(&spec.verify, literals, r.verify_time_s),
        },
    ]
}

/// The job parameters' values: in Deadline Cloud's job-bundle form (YAML) and as `openjd run`
/// takes them (JSON text).
fn openjd_values(spec: &JobSpec) -> (OpenjdParameterValues, String) {
    let values = [
        ("Shards", spec.shards.to_string()),
        ("InputList", openjd_input_list_path(spec)),
        ("Model", spec.model.clone()),
        ("OutputDir", spec.output_dir.clone()),
        ("NsrmProgram", spec.program.clone()),
    ];
    let json: serde_json::Map<String, serde_json::Value> = values
        .iter()
        .map(|(k, v)| (k.to_string(), serde_json::Value::String(v.clone())))
        .collect();
    let mut json = serde_json::to_string_pretty(&json).unwrap_or_default();
    json.push('\n');
    let bundle_values = OpenjdParameterValues {
        parameter_values: values
            .into_iter()
            .map(|(name, value)| OpenjdParameterValue { name, value })
            .collect(),
    };
    (bundle_values, json)
}

/// A word for a POSIX shell, single-quoted unless it is plainly safe.
pub(crate) fn sh_quote(s: &str) -> String {
    if !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-_./=:,+@%".contains(&b))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// A delimiter for a here-document that no line of `text` equals.
fn heredoc_end(text: &str) -> String {
    let mut end = "NSRM_INPUTS_END".to_string();
    while text.lines().any(|l| l == end) {
        end.push('_');
    }
    end
}

/// The shell words of a command, with the engine's values for the placeholders.
fn sh_command(
    spec: &JobSpec,
    list: &[Arg],
    shard: &str,
    input_list: &str,
) -> Result<String, FarmError> {
    let mut words = vec![sh_quote(&spec.program)];
    for a in list {
        words.push(match a {
            Arg::Lit(s) => sh_quote(s),
            Arg::Shard => shard.to_string(),
            Arg::Shards => spec.shards.to_string(),
            Arg::InputList => sh_quote(input_list),
            Arg::PathMappingRules => {
                return Err(FarmError::Usage(
                    "path-mapping rule files are Open Job Description's; map the paths when the job is made".into(),
                ))
            }
            Arg::Model => sh_quote(&spec.model),
            Arg::OutputDir => sh_quote(&spec.output_dir),
        });
    }
    Ok(words.join(" "))
}

/// A Slurm job: `array.sbatch` (an array job of `1-N` tasks, task `K` running shard `K/N` with
/// the input list on its standard input), `verify.sbatch`, and `submit.sh`, which submits the
/// array and then the verification with a dependency on every task of it (`afterany`, so the
/// verification always reports, also on a failed task).
pub(crate) fn slurm(spec: &JobSpec) -> Result<Vec<JobFile>, FarmError> {
    spec.check()?;
    let list = spec.input_list();
    let end = heredoc_end(&list);
    let n = spec.shards;
    let task = sh_command(
        spec,
        &spec.task,
        &format!("\"$SLURM_ARRAY_TASK_ID/{n}\""),
        "-",
    )?;
    let verify = sh_command(spec, &spec.verify, "", "")?;
    let array = format!(
        "#!/bin/sh\n\
         # nsrm: {inputs} input(s) in {n} shard(s). Task K of the array converts shard K/{n} and writes\n\
         # its manifest beside the outputs; a re-run of a task keeps what is finished.\n\
         #SBATCH -J {name}\n\
         #SBATCH -a 1-{n}\n\
         #SBATCH -o {name}-%A_%a.out\n\
         {res}\
         set -eu\n\
         exec {task} <<'{end}'\n{list}{end}\n",
        inputs = spec.inputs.len(),
        name = spec.name,
        res = spec.resources.sbatch_lines(true),
    );
    let verify = format!(
        "#!/bin/sh\n\
         # nsrm: checks every shard's outputs against its manifest.\n\
         #SBATCH -J {name}-verify\n\
         #SBATCH -o {name}-verify-%j.out\n\
         {res}\
         set -eu\n\
         exec {verify}\n",
        name = spec.name,
        res = spec.resources.sbatch_lines(false),
    );
    let submit = "#!/bin/sh\n\
         # Submits the array job, then the verification once every task of it has ended.\n\
         set -eu\n\
         cd \"$(dirname \"$0\")\"\n\
         array=$(sbatch --parsable array.sbatch)\n\
         array=${array%%;*}\n\
         verify=$(sbatch --parsable --dependency=afterany:\"$array\" verify.sbatch)\n\
         echo \"array job $array, verification job ${verify%%;*}\"\n"
        .to_string();
    Ok(vec![
        JobFile {
            name: "array.sbatch".into(),
            text: array,
            executable: true,
        },
        JobFile {
            name: "verify.sbatch".into(),
            text: verify,
            executable: true,
        },
        JobFile {
            name: "submit.sh".into(),
            text: submit,
            executable: true,
        },
    ])
}

/// Where a Kubernetes job runs: the container image, and the persistent volume claim holding
/// the inputs, model and outputs, mounted at `mount_path` (the paths in the job are as the
/// pods see them).
#[derive(Debug, Clone)]
pub(crate) struct Kube {
    pub image: String,
    pub claim: String,
    pub mount_path: String,
    /// Pods at once.
    pub parallelism: usize,
    /// Retries of one index before it counts as failed.
    pub retries_per_index: usize,
}

/// Where the input list (a ConfigMap) is mounted in the pods.
pub(crate) const KUBE_LIST_DIR: &str = "/etc/nsrm-batch";

/// A Kubernetes batch: `job.yaml` with a ConfigMap holding the input list and an Indexed Job
/// (`completionMode: Indexed`, `completions: N`) whose pod `JOB_COMPLETION_INDEX` (0-based) runs
/// shard `index + 1`; `verify.yaml`, a Job to apply once the first has completed
/// (Kubernetes orders no jobs).
pub(crate) fn kube(spec: &JobSpec, k: &Kube) -> Result<Vec<JobFile>, FarmError> {
    super::resources::check_kube_name(&spec.name)?;
    spec.check()?;
    if k.parallelism == 0 {
        return Err(FarmError::Usage("parallelism must be at least 1".into()));
    }
    let n = spec.shards;
    let list_path = format!("{KUBE_LIST_DIR}/inputs.txt");
    let task = sh_command(spec, &spec.task, "\"$shard\"", &list_path)?;
    let script = format!("set -eu\nshard=\"$((JOB_COMPLETION_INDEX + 1))/{n}\"\nexec {task}\n");
    let verify = sh_command(spec, &spec.verify, "", "")?;
    let verify = format!("exec {verify}");
    let config = to_yaml(&kube_config_map(spec))?;
    let job = to_yaml(&kube_indexed_job(spec, k, &script))?;
    Ok(vec![
        JobFile {
            name: "job.yaml".into(),
            text: format!("{config}---\n{job}"),
            executable: false,
        },
        JobFile {
            name: "verify.yaml".into(),
            text: to_yaml(&kube_verify_job(spec, k, &verify))?,
            executable: false,
        },
        JobFile {
            name: "wait.sh".into(),
            text: kube_wait_script(&spec.name),
            executable: true,
        },
    ])
}

/// Seconds a finished Job (and its pods' logs) is kept before Kubernetes deletes it.
const KUBE_TTL_S: u64 = 7 * 24 * 3600;

/// `wait.sh`: waits until the Job `name` is `Complete` or `Failed` (a `kubectl wait
/// --for=condition=complete` alone waits forever on a failed Job), says which, and exits 0 only
/// when it completed.
fn kube_wait_script(name: &str) -> String {
    format!(
        "#!/bin/sh\n\
         # Waits for the Job {name} to end: exit 0 when it is Complete, 1 when it Failed.\n\
         set -eu\n\
         job=job/{name}\n\
         while :; do\n\
         \x20   state=$(kubectl get \"$job\" -o jsonpath='{{.status.conditions[?(@.status==\"True\")].type}}')\n\
         \x20   case \" $state \" in\n\
         \x20   *\" Complete \"*) echo \"$job: Complete\"; exit 0 ;;\n\
         \x20   *\" Failed \"*) echo \"$job: Failed (kubectl describe $job; kubectl logs $job)\" >&2; exit 1 ;;\n\
         \x20   esac\n\
         \x20   sleep 10\n\
         done\n"
    )
}

/// The labels of every object of a batch: the program, the job's name and the batch's own
/// (`kubectl get jobs,pods,configmaps -l nsrm.batch=nsrm-…` finds all of one batch).
#[derive(Debug, Clone, Serialize)]
struct KubeLabels<'a> {
    #[serde(rename = "app.kubernetes.io/name")]
    app: &'static str,
    #[serde(rename = "app.kubernetes.io/instance")]
    instance: &'a str,
    #[serde(rename = "nsrm.batch")]
    batch: &'a str,
}

fn kube_labels(spec: &JobSpec) -> KubeLabels<'_> {
    KubeLabels {
        app: "nsrm",
        instance: &spec.name,
        batch: &spec.batch,
    }
}

/// An object's `metadata` (a pod template's has no name).
#[derive(Debug, Serialize)]
struct KubeMetadata<'a> {
    #[serde(skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    labels: KubeLabels<'a>,
}

/// The ConfigMap holding the input list.
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubeConfigMap<'a> {
    api_version: &'static str,
    kind: &'static str,
    metadata: KubeMetadata<'a>,
    data: KubeConfigData,
}

#[derive(Debug, PartialEq, Serialize)]
struct KubeConfigData {
    #[serde(rename = "inputs.txt")]
    inputs: String,
}

/// A Job: the Indexed Job of the shards (`completionMode` … `backoffLimitPerIndex`) or the
/// verification's (`backoffLimit`).
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubeJob<'a> {
    api_version: &'static str,
    kind: &'static str,
    metadata: KubeMetadata<'a>,
    spec: KubeJobSpec<'a>,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubeJobSpec<'a> {
    #[serde(skip_serializing_if = "Option::is_none")]
    completion_mode: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    completions: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    parallelism: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    backoff_limit_per_index: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    backoff_limit: Option<usize>,
    ttl_seconds_after_finished: u64,
    template: KubePodTemplate<'a>,
}

#[derive(Debug, Serialize)]
struct KubePodTemplate<'a> {
    metadata: KubeMetadata<'a>,
    spec: KubePodSpec<'a>,
}

/// A pod spec: never restarted in place, one container, the volumes, then the scheduling
/// fields and the `--pod-spec` pass-through.
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubePodSpec<'a> {
    restart_policy: &'static str,
    containers: Vec<KubeContainer<'a>>,
    volumes: Vec<KubeVolume<'a>>,
    #[serde(flatten)]
    scheduling: super::resources::KubeScheduling<'a>,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubeContainer<'a> {
    name: &'static str,
    image: &'a str,
    command: [&'a str; 3],
    #[serde(skip_serializing_if = "Option::is_none")]
    resources: Option<super::resources::KubeResources<'a>>,
    volume_mounts: Vec<KubeMount<'a>>,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubeMount<'a> {
    name: &'static str,
    mount_path: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    read_only: Option<bool>,
}

/// A volume: the claim or the input list's ConfigMap.
#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubeVolume<'a> {
    name: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    persistent_volume_claim: Option<KubeClaimRef<'a>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    config_map: Option<KubeConfigMapRef>,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "camelCase")]
struct KubeClaimRef<'a> {
    claim_name: &'a str,
}

#[derive(Debug, Serialize)]
struct KubeConfigMapRef {
    name: String,
}

/// A pod's volume mounts and volumes: the claim at `mount_path`, and with `with_list` the
/// input list's ConfigMap at [`KUBE_LIST_DIR`].
fn kube_volumes<'a>(
    spec: &JobSpec,
    k: &'a Kube,
    with_list: bool,
) -> (Vec<KubeMount<'a>>, Vec<KubeVolume<'a>>) {
    let mut mounts = vec![KubeMount {
        name: "data",
        mount_path: &k.mount_path,
        read_only: None,
    }];
    let mut volumes = vec![KubeVolume {
        name: "data",
        persistent_volume_claim: Some(KubeClaimRef {
            claim_name: &k.claim,
        }),
        config_map: None,
    }];
    if with_list {
        mounts.push(KubeMount {
            name: "batch",
            mount_path: KUBE_LIST_DIR,
            read_only: Some(true),
        });
        volumes.push(KubeVolume {
            name: "batch",
            persistent_volume_claim: None,
            config_map: Some(KubeConfigMapRef {
                name: format!("{}-inputs", spec.name),
            }),
        });
    }
    (mounts, volumes)
}

/// The pod template of a Job: its container `name` running the shell `script` with the task's
/// resources (`task`) or the verification's, the claim and with `task` the input list.
fn kube_pod_template<'a>(
    spec: &'a JobSpec,
    k: &'a Kube,
    name: &'static str,
    script: &'a str,
    task: bool,
) -> KubePodTemplate<'a> {
    let (volume_mounts, volumes) = kube_volumes(spec, k, task);
    KubePodTemplate {
        metadata: KubeMetadata {
            name: None,
            labels: kube_labels(spec),
        },
        spec: KubePodSpec {
            restart_policy: "Never",
            containers: vec![KubeContainer {
                name,
                image: &k.image,
                command: ["/bin/sh", "-c", script],
                resources: spec.resources.kube_resources(task),
                volume_mounts,
            }],
            volumes,
            scheduling: spec.resources.kube_pod_fields(task),
        },
    }
}

/// The ConfigMap `NAME-inputs` holding the input list as `inputs.txt`.
fn kube_config_map(spec: &JobSpec) -> KubeConfigMap<'_> {
    KubeConfigMap {
        api_version: "v1",
        kind: "ConfigMap",
        metadata: KubeMetadata {
            name: Some(format!("{}-inputs", spec.name)),
            labels: kube_labels(spec),
        },
        data: KubeConfigData {
            inputs: spec.input_list(),
        },
    }
}

/// The Indexed Job whose pods run the shell `script` (one shard each).
fn kube_indexed_job<'a>(spec: &'a JobSpec, k: &'a Kube, script: &'a str) -> KubeJob<'a> {
    let n = spec.shards;
    KubeJob {
        api_version: "batch/v1",
        kind: "Job",
        metadata: KubeMetadata {
            name: Some(spec.name.clone()),
            labels: kube_labels(spec),
        },
        spec: KubeJobSpec {
            completion_mode: Some("Indexed"),
            completions: Some(n),
            parallelism: Some(k.parallelism.min(n)),
            backoff_limit_per_index: Some(k.retries_per_index),
            backoff_limit: None,
            ttl_seconds_after_finished: KUBE_TTL_S,
            template: kube_pod_template(spec, k, "nsrm", script, true),
        },
    }
}

/// The Job `NAME-verify`, one pod running the shell `script` once, never retried.
fn kube_verify_job<'a>(spec: &'a JobSpec, k: &'a Kube, script: &'a str) -> KubeJob<'a> {
    KubeJob {
        api_version: "batch/v1",
        kind: "Job",
        metadata: KubeMetadata {
            name: Some(format!("{}-verify", spec.name)),
            labels: kube_labels(spec),
        },
        spec: KubeJobSpec {
            completion_mode: None,
            completions: None,
            parallelism: None,
            backoff_limit_per_index: None,
            backoff_limit: Some(0),
            ttl_seconds_after_finished: KUBE_TTL_S,
            template: kube_pod_template(spec, k, "verify", script, false),
        },
    }
}

#[cfg(test)]
#[path = "jobs_tests.rs"]
mod tests;
