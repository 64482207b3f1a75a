//! The help the command line prints: `-h` gives each option's and command's first sentence (one
//! line each, so a command's options fit on a screen), `--help` the whole text; every command
//! ends with examples (`after_help`), which a test parses so they cannot drift from the flags.

use clap::Command;

/// The longest one-line help `-h` prints for an option or command, in characters.
const SHORT_MAX: usize = 80;

/// Words after which a full stop does not end a sentence.
const ABBREVIATIONS: [&str; 6] = ["e.g", "i.e", "etc", "vs", "cf", "approx"];

/// The first sentence of `text` (its first paragraph, to the first `. `, `; ` or a `: ` after
/// a few words), shortened to [`SHORT_MAX`] characters at a comma or bracket outside brackets;
/// `None` when that is the whole text.
pub(crate) fn first_sentence(text: &str) -> Option<String> {
    let para = text.split("\n\n").next().unwrap_or(text).trim();
    let mut end = para.len();
    let mut depth = 0i32;
    let b = para.as_bytes();
    for (i, &c) in b.iter().enumerate() {
        match c {
            b'(' | b'[' => depth += 1,
            b')' | b']' => depth -= 1,
            b'.' | b';' | b':' if depth == 0 && b.get(i + 1) == Some(&b' ') => {
                let before = &para[..i];
                let word = before.rsplit([' ', '(']).next().unwrap_or("");
                let abbreviation = c == b'.'
                    && (ABBREVIATIONS.contains(&word.to_ascii_lowercase().as_str())
                        || word.chars().count() == 1);
                let early = c == b':' && before.chars().count() < 12;
                if !abbreviation && !early {
                    end = i;
                    break;
                }
            }
            _ => {}
        }
    }
    let mut short = para[..end].trim_end_matches(['.', ',']).to_string();
    if short.chars().count() > SHORT_MAX {
        short = cut(&short);
    }
    (short != text.trim().trim_end_matches('.')).then_some(short)
}

/// `s` cut at its last `, ` or ` (` outside brackets within [`SHORT_MAX`] characters, with `…`.
fn cut(s: &str) -> String {
    let mut depth = 0i32;
    let mut best = None;
    for (n, (i, c)) in s.char_indices().enumerate() {
        if n >= SHORT_MAX {
            break;
        }
        match c {
            '(' | '[' => {
                if depth == 0 && i > 0 && s[..i].ends_with(' ') {
                    best = Some(i - 1);
                }
                depth += 1;
            }
            ')' | ']' => depth -= 1,
            ',' if depth == 0 => best = Some(i),
            _ => {}
        }
    }
    match best {
        Some(i) if i > 20 => format!("{}…", &s[..i]),
        _ => {
            let at = s
                .char_indices()
                .take(SHORT_MAX)
                .filter(|&(_, c)| c == ' ')
                .map(|(i, _)| i)
                .last()
                .unwrap_or(s.len());
            format!("{}…", &s[..at])
        }
    }
}

/// Examples of each command (its path below `nsrm`), printed after its help. Each line is a
/// whole command line without quotes (a test parses every one).
pub(crate) const EXAMPLES: &[(&str, &[&str])] = &[
    (
        "apply",
        &[
            "nsrm apply --model calibration/model.json -o corrected shots/*.dng",
            "nsrm apply --model m.json --output-space acescg --device gpu -o out plates/",
            "nsrm apply --model dual.json --white as-shot --highlights clip --jobs 4 shots/",
        ],
    ),
    (
        "bench",
        &[
            "nsrm bench",
            "nsrm bench --size 6000x4000 --layout rgba --kinds nsrm --device cpu",
            "nsrm bench --json",
        ],
    ),
    (
        "calibrate",
        &[
            "nsrm calibrate chart.dng -o calibration",
            "nsrm calibrate chart.dng -o calibration --export dcp,icc",
            "nsrm calibrate chart.exr -o calibration --chart sg --kind nsrm --order 3",
            "nsrm calibrate spyder.dng -o calibration --chart spyder24",
        ],
    ),
    (
        "chart extract",
        &[
            "nsrm chart extract chart.dng --chart cc24 -o patches.csv",
            "nsrm chart extract shot.exr --chart cc24 --flat greycard.exr -o patches.csv --overlay reading.png",
            "nsrm chart extract photo.jpg --chart auto -o patches.csv",
        ],
    ),
    (
        "chart rate",
        &[
            "nsrm chart rate --chart cc24 --scenes 3",
            "nsrm chart rate --chart sg --family tilt --scenes 20",
        ],
    ),
    (
        "chart time",
        &[
            "nsrm chart time --chart cc24 shot.exr",
            "nsrm chart time --chart sg --repeat 5 a.dng b.dng",
        ],
    ),
    (
        "combine",
        &["nsrm combine nsrm-a.json nsrm-d65.json -o nsrm-dual.json"],
    ),
    (
        "eval",
        &[
            "nsrm eval",
            "nsrm eval --training patches.csv",
            "nsrm eval --orders 1-4 --illuminant FL7 --json",
        ],
    ),
    (
        "export",
        &[
            "nsrm export --model m.json --format clf --output-space acescg -o camera.clf",
            "nsrm export --model m.json --format cube --lut-size 33 -o m.cube",
            "nsrm export --model calibration/model.json --format dcp -o camera.dcp",
        ],
    ),
    (
        "export-shader",
        &[
            "nsrm export-shader --model m.json --lang wgsl -o m.wgsl",
            "nsrm export-shader --model m.json --lang dctl --output-space acescg -o m.dctl",
        ],
    ),
    (
        "farm openjd",
        &[
            "nsrm farm openjd --shards 8 --job-dir job --model m.json -o /show/out /show/plates",
            "nsrm farm openjd --shards 8 --job-dir job --os-family linux --gpus 1 --model m.json -o out plates",
        ],
    ),
    (
        "farm slurm",
        &[
            "nsrm farm slurm --shards 8 --job-dir job --model m.json -o out plates",
            "nsrm farm slurm --shards 8 --job-dir job --cpus 4 --mem 8G --time 1:00:00 --partition gpu --model m.json -o out plates",
        ],
    ),
    (
        "farm k8s",
        &[
            "nsrm farm k8s --shards 8 --job-dir job --image nsrm:1 --claim show --path-map /show=/data --model m.json -o /show/out /show/plates",
            "nsrm farm k8s --shards 8 --job-dir job --image nsrm:1 --claim show --gpus 1 --toleration nvidia.com/gpu:NoSchedule --model m.json -o out plates",
        ],
    ),
    (
        "farm run",
        &["nsrm farm run --shard 1/8 -- --model m.json -o out plates"],
    ),
    (
        "farm verify",
        &[
            "nsrm farm verify out",
            "nsrm farm verify out --shards 8 --model m.json",
        ],
    ),
    (
        "fit",
        &[
            "nsrm fit --kind nsrm --order 3 -o m.json",
            "nsrm fit --training patches.csv --kind rprm --order 2 -o m.json",
            "nsrm fit --capture chart.dng --chart cc24 --kind nsrm -o m.json",
        ],
    ),
    (
        "terms",
        &["nsrm terms --kind nsrm --order 3", "nsrm terms --kind rprm --order 2"],
    ),
    (
        "render-chart",
        &[
            "nsrm render-chart -o chart.exr",
            "nsrm render-chart --camera nikon-d5100 --illuminant A -o chart.tif",
        ],
    ),
    (
        "render-scene",
        &[
            "nsrm render-scene --chart cc24 --seed 3 -o scene.exr",
            "nsrm render-scene --chart cc24 --family jpeg --seed 4 -o jpeg.exr",
        ],
    ),
    (
        "studio",
        &["nsrm studio", "nsrm studio --device cpu --no-browser shots/"],
    ),
];

/// `cmd` (the one at `path` below `nsrm`) and its subcommands with short `-h` help and their
/// examples.
fn finish(cmd: Command, path: &str) -> Command {
    let mut cmd = cmd.mut_args(|a| {
        if a.get_long_help().is_some() {
            return a;
        }
        let Some(full) = a.get_help().map(ToString::to_string) else {
            return a;
        };
        match first_sentence(&full) {
            Some(short) => a.help(short).long_help(full),
            None => a,
        }
    });
    if cmd.get_long_about().is_none() {
        if let Some(full) = cmd.get_about().map(ToString::to_string) {
            if let Some(short) = first_sentence(&full) {
                cmd = cmd.about(short).long_about(full);
            }
        }
    }
    if let Some((_, lines)) = EXAMPLES.iter().find(|(p, _)| *p == path) {
        let text = format!("Examples:\n  {}", lines.join("\n  "));
        cmd = cmd.after_help(text.clone()).after_long_help(text);
    }
    let names: Vec<String> = cmd
        .get_subcommands()
        .map(|s| s.get_name().to_string())
        .collect();
    for name in names {
        let sub = if path.is_empty() {
            name.clone()
        } else {
            format!("{path} {name}")
        };
        cmd = cmd.mut_subcommand(&name, |s| finish(s, &sub));
    }
    cmd
}

/// The options of `apply` that a farm job file passes on to each task, but that its `-h`
/// leaves to `--help` (it shows the job's own, and the model, output and inputs).
fn apply_only(cmd: &Command) -> Vec<String> {
    cmd.find_subcommand("apply")
        .map(|a| {
            a.get_arguments()
                .map(|x| x.get_id().to_string())
                .filter(|id| {
                    !matches!(
                        id.as_str(),
                        "model" | "output" | "inputs" | "help" | "version"
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The heading of apply's options in a farm job generator's `--help`.
const TASK_OPTIONS: &str = "Options of each task (apply's; `-h` hides them)";

/// The `nsrm` command as it parses and prints: `cmd` (the derived one) finished with short
/// help and examples; the farm job generators' `-h` shows their own options, `--help` apply's
/// as well.
pub(crate) fn command(cmd: Command) -> Command {
    let apply = apply_only(&cmd);
    let cmd = cmd.mut_subcommand("farm", |farm| {
        let mut farm = farm;
        for engine in ["openjd", "slurm", "k8s"] {
            farm = farm.mut_subcommand(engine, |mut e| {
                for id in &apply {
                    if e.get_arguments().any(|a| a.get_id() == id.as_str()) {
                        e = e.mut_arg(id, |a| a.hide_short_help(true).help_heading(TASK_OPTIONS));
                    }
                }
                e
            });
        }
        farm
    });
    finish(cmd, "")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_sentence_is_the_short_help() {
        let f = |s: &str| first_sentence(s);
        assert_eq!(f("Replace existing outputs (never inputs)"), None);
        assert_eq!(
            f("Output directory (created if missing); default: beside each input"),
            Some("Output directory (created if missing)".into())
        );
        assert_eq!(
            f("Wall-time limit per task, e.g. 1:00:00. Slurm's forms are many."),
            Some("Wall-time limit per task, e.g. 1:00:00".into())
        );
        assert_eq!(
            f("Where to run: `auto` (a GPU if there is one), `gpu` or `cpu`"),
            Some("Where to run".into())
        );
        assert_eq!(f("Kind: lrm or prm"), None, "a colon after one word");
        let long = "A very long first sentence that goes on and on, naming a great many things (and more, inside brackets, that never end) and then some more words after it";
        let s = f(long).unwrap();
        assert!(
            s.chars().count() <= SHORT_MAX + 1 && s.ends_with('…'),
            "{s}"
        );
        assert_eq!(s.matches('(').count(), s.matches(')').count(), "{s}");
    }
}
