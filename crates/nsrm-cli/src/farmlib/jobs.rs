//! Job descriptions in the engines' own formats: an Open Job Description template (the format
//! AWS Deadline Cloud submits, laid out as a job bundle), a Slurm array script with a dependent
//! verification job, and a Kubernetes Indexed Job.
//!
//! The caller gives the command a worker runs for a shard and for the verification as a list of
//! [`Arg`]s: literal words and the places where each engine puts its own values (the shard, the
//! input list, the model, the output directory). Every file is generated text; nothing here
//! runs anything.

use super::yaml::{self, Node};
use super::FarmError;

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
    let template = Node::map([
        ("specificationVersion", Node::str("jobtemplate-2023-09")),
        ("name", Node::str(&spec.name)),
        (
            "description",
            Node::str(format!(
                "nsrm: {} input(s) in {} shard(s); each shard writes a manifest beside its outputs, the Verify step checks the batch is whole",
                spec.inputs.len(),
                spec.shards
            )),
        ),
        ("parameterDefinitions", openjd_parameters(spec, &literals)),
        ("steps", openjd_steps(spec, &literals)),
    ]);
    let (bundle_values, json) = openjd_values(spec);
    let file = |name: &str, text: String| JobFile {
        name: name.into(),
        text,
        executable: false,
    };
    Ok(vec![
        file("template.yaml", yaml::to_string(&template)),
        file("parameter_values.yaml", yaml::to_string(&bundle_values)),
        file(OPENJD_RUN_VALUES, json),
        file(OPENJD_INPUT_LIST, spec.input_list()),
        file(
            "asset_references.yaml",
            yaml::to_string(&openjd_asset_references(spec)),
        ),
    ])
}

/// `asset_references.yaml`: the inputs as files job attachments upload, the output (and
/// preview) directories as those they download.
fn openjd_asset_references(spec: &JobSpec) -> Node {
    let mut outputs = vec![spec.output_dir.clone()];
    outputs.extend(spec.preview_dir.iter().cloned());
    Node::map([(
        "assetReferences",
        Node::map([
            (
                "inputs",
                Node::map([
                    ("filenames", Node::strs(spec.inputs.iter().cloned())),
                    ("directories", Node::List(Vec::new())),
                ]),
            ),
            ("outputs", Node::map([("directories", Node::strs(outputs))])),
            ("referencedPaths", Node::List(Vec::new())),
        ]),
    )])
}

/// The path of the bundle's input list as the submitter names it.
fn openjd_input_list_path(spec: &JobSpec) -> String {
    format!("{}/{OPENJD_INPUT_LIST}", spec.job_dir.trim_end_matches('/'))
}

/// The template's job parameters: `Shards` (INT), `InputList`, `Model` and `OutputDir` (PATH),
/// `NsrmProgram` and the `literals` (STRING).
fn openjd_parameters(spec: &JobSpec, literals: &[String]) -> Node {
    let param = |name: &str, ty: &str, extra: Vec<(&str, Node)>| {
        let mut pairs = vec![("name", Node::str(name)), ("type", Node::str(ty))];
        pairs.extend(extra);
        Node::map(pairs)
    };
    let path = |name: &str, object: &str, flow: &str, what: &str| {
        param(
            name,
            "PATH",
            vec![
                ("objectType", Node::str(object)),
                ("dataFlow", Node::str(flow)),
                ("description", Node::str(what)),
            ],
        )
    };
    let mut params = vec![
        param(
            "Shards",
            "INT",
            vec![
                ("default", Node::Int(spec.shards as i64)),
                ("minValue", Node::Int(1)),
                (
                    "description",
                    Node::str("Shards the batch is split into (one task each)"),
                ),
            ],
        ),
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
            vec![
                ("default", Node::str(&spec.program)),
                ("description", Node::str("The nsrm program on the workers")),
            ],
        ),
    ];
    for (i, l) in literals.iter().enumerate() {
        params.push(param(
            &format!("NsrmArg{}", i + 1),
            "STRING",
            vec![
                ("default", Node::str(l)),
                (
                    "description",
                    Node::str("A word of nsrm's command line (a parameter, so that it is never read as a template)"),
                ),
            ],
        ));
    }
    Node::List(params)
}

/// The action running `{{Param.NsrmProgram}}` with `list`'s arguments, stopped after
/// `timeout_s` seconds when given.
fn openjd_action(list: &[Arg], literals: &[String], timeout_s: Option<u64>) -> Node {
    let args = Node::List(
        list.iter()
            .map(|a| Node::Str(openjd_arg(a, literals)))
            .collect(),
    );
    let mut run = vec![
        ("command", Node::str("{{Param.NsrmProgram}}")),
        ("args", args),
    ];
    if let Some(t) = timeout_s {
        run.push(("timeout", Node::Int(t as i64)));
    }
    Node::map([("onRun", Node::map(run))])
}

/// A step's pairs with its `hostRequirements` (`task`: the Apply step's) before `script`.
fn openjd_step(spec: &JobSpec, mut pairs: Vec<(&str, Node)>, task: bool) -> Node {
    if let Some(h) = spec.resources.openjd_host_requirements(task) {
        let at = pairs.len() - 1;
        pairs.insert(at, ("hostRequirements", h));
    }
    Node::map(pairs)
}

/// The template's steps: `Apply` (a task per shard) and `Verify` after it.
fn openjd_steps(spec: &JobSpec, literals: &[String]) -> Node {
    let timeout = spec.resources.time_s;
    Node::List(vec![
        openjd_step(
            spec,
            vec![
                ("name", Node::str("Apply")),
                (
                    "parameterSpace",
                    Node::map([(
                        "taskParameterDefinitions",
                        Node::List(vec![Node::map([
                            ("name", Node::str("Shard")),
                            ("type", Node::str("INT")),
                            ("range", Node::str("1-{{Param.Shards}}")),
                        ])]),
                    )]),
                ),
                (
                    "script",
                    Node::map([("actions", openjd_action(&spec.task, literals, timeout))]),
                ),
            ],
            true,
        ),
        openjd_step(
            spec,
            vec![
                ("name", Node::str("Verify")),
                (
                    "dependencies",
                    Node::List(vec![Node::map([("dependsOn", Node::str("Apply"))])]),
                ),
                (
                    "script",
                    Node::map([(
                        "actions",
                        openjd_action(&spec.verify, literals, spec.resources.verify_time_s),
                    )]),
                ),
            ],
            false,
        ),
    ])
}

/// The job parameters' values: in Deadline Cloud's job-bundle form (YAML) and as `openjd run`
/// takes them (JSON text).
fn openjd_values(spec: &JobSpec) -> (Node, String) {
    let values = [
        ("Shards", spec.shards.to_string()),
        ("InputList", openjd_input_list_path(spec)),
        ("Model", spec.model.clone()),
        ("OutputDir", spec.output_dir.clone()),
        ("NsrmProgram", spec.program.clone()),
    ];
    let bundle_values = Node::map([(
        "parameterValues",
        Node::List(
            values
                .iter()
                .map(|(k, v)| Node::map([("name", Node::str(*k)), ("value", Node::str(v))]))
                .collect(),
        ),
    )]);
    let json: serde_json::Map<String, serde_json::Value> = values
        .iter()
        .map(|(k, v)| (k.to_string(), serde_json::Value::String(v.clone())))
        .collect();
    let mut json = serde_json::to_string_pretty(&json).unwrap_or_default();
    json.push('\n');
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
    let config = kube_config_map(spec);
    let job = kube_indexed_job(spec, k, &script);
    let verify_job = kube_verify_job(spec, k, &format!("exec {verify}"));
    Ok(vec![
        JobFile {
            name: "job.yaml".into(),
            text: format!("{}---\n{}", yaml::to_string(&config), yaml::to_string(&job)),
            executable: false,
        },
        JobFile {
            name: "verify.yaml".into(),
            text: yaml::to_string(&verify_job),
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
const KUBE_TTL_S: i64 = 7 * 24 * 3600;

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
fn kube_labels(spec: &JobSpec) -> Node {
    Node::map([
        ("app.kubernetes.io/name", Node::str("nsrm")),
        ("app.kubernetes.io/instance", Node::str(&spec.name)),
        ("nsrm.batch", Node::str(&spec.batch)),
    ])
}

/// A pod's single container `name` running `script`, with the task's resources (`task`) or
/// the verification's.
fn kube_container(
    spec: &JobSpec,
    k: &Kube,
    name: &str,
    script: &str,
    mounts: Node,
    task: bool,
) -> Node {
    let mut pairs = vec![
        ("name", Node::str(name)),
        ("image", Node::str(&k.image)),
        ("command", Node::strs(["/bin/sh", "-c", script])),
    ];
    if let Some(r) = spec.resources.kube_resources(task) {
        pairs.push(("resources", r));
    }
    pairs.push(("volumeMounts", mounts));
    Node::map(pairs)
}

/// A pod spec: never restarted in place, `container`, the volumes and the scheduling fields.
fn kube_pod_spec(spec: &JobSpec, container: Node, volumes: Node, task: bool) -> Node {
    let mut pairs = vec![
        ("restartPolicy".to_string(), Node::str("Never")),
        ("containers".to_string(), Node::List(vec![container])),
        ("volumes".to_string(), volumes),
    ];
    pairs.extend(spec.resources.kube_pod_fields(task));
    Node::map(pairs)
}

/// A pod's volume mounts and volumes: the claim at `mount_path`, and with `with_list` the
/// input list's ConfigMap at [`KUBE_LIST_DIR`].
fn kube_volumes(spec: &JobSpec, k: &Kube, with_list: bool) -> (Node, Node) {
    let mut mounts = vec![Node::map([
        ("name", Node::str("data")),
        ("mountPath", Node::str(&k.mount_path)),
    ])];
    let mut volumes = vec![Node::map([
        ("name", Node::str("data")),
        (
            "persistentVolumeClaim",
            Node::map([("claimName", Node::str(&k.claim))]),
        ),
    ])];
    if with_list {
        mounts.push(Node::map([
            ("name", Node::str("batch")),
            ("mountPath", Node::str(KUBE_LIST_DIR)),
            ("readOnly", Node::Bool(true)),
        ]));
        volumes.push(Node::map([
            ("name", Node::str("batch")),
            (
                "configMap",
                Node::map([("name", Node::str(format!("{}-inputs", spec.name)))]),
            ),
        ]));
    }
    (Node::List(mounts), Node::List(volumes))
}

/// The ConfigMap `NAME-inputs` holding the input list as `inputs.txt`.
fn kube_config_map(spec: &JobSpec) -> Node {
    Node::map([
        ("apiVersion", Node::str("v1")),
        ("kind", Node::str("ConfigMap")),
        (
            "metadata",
            Node::map([
                ("name", Node::str(format!("{}-inputs", spec.name))),
                ("labels", kube_labels(spec)),
            ]),
        ),
        (
            "data",
            Node::map([("inputs.txt", Node::str(spec.input_list()))]),
        ),
    ])
}

/// The Indexed Job whose pods run the shell `script` (one shard each).
fn kube_indexed_job(spec: &JobSpec, k: &Kube, script: &str) -> Node {
    let n = spec.shards;
    let (mounts, volumes) = kube_volumes(spec, k, true);
    Node::map([
        ("apiVersion", Node::str("batch/v1")),
        ("kind", Node::str("Job")),
        (
            "metadata",
            Node::map([
                ("name", Node::str(&spec.name)),
                ("labels", kube_labels(spec)),
            ]),
        ),
        (
            "spec",
            Node::map([
                ("completionMode", Node::str("Indexed")),
                ("completions", Node::Int(n as i64)),
                ("parallelism", Node::Int(k.parallelism.min(n) as i64)),
                (
                    "backoffLimitPerIndex",
                    Node::Int(k.retries_per_index as i64),
                ),
                ("ttlSecondsAfterFinished", Node::Int(KUBE_TTL_S)),
                (
                    "template",
                    Node::map([
                        ("metadata", Node::map([("labels", kube_labels(spec))])),
                        (
                            "spec",
                            kube_pod_spec(
                                spec,
                                kube_container(spec, k, "nsrm", script, mounts, true),
                                volumes,
                                true,
                            ),
                        ),
                    ]),
                ),
            ]),
        ),
    ])
}

/// The Job `NAME-verify`, one pod running the shell `script` once, never retried.
fn kube_verify_job(spec: &JobSpec, k: &Kube, script: &str) -> Node {
    let (mounts, volumes) = kube_volumes(spec, k, false);
    Node::map([
        ("apiVersion", Node::str("batch/v1")),
        ("kind", Node::str("Job")),
        (
            "metadata",
            Node::map([
                ("name", Node::str(format!("{}-verify", spec.name))),
                ("labels", kube_labels(spec)),
            ]),
        ),
        (
            "spec",
            Node::map([
                ("backoffLimit", Node::Int(0)),
                ("ttlSecondsAfterFinished", Node::Int(KUBE_TTL_S)),
                (
                    "template",
                    Node::map([
                        ("metadata", Node::map([("labels", kube_labels(spec))])),
                        (
                            "spec",
                            kube_pod_spec(
                                spec,
                                kube_container(spec, k, "verify", script, mounts, false),
                                volumes,
                                false,
                            ),
                        ),
                    ]),
                ),
            ]),
        ),
    ])
}

#[cfg(test)]
#[path = "jobs_tests.rs"]
mod tests;
