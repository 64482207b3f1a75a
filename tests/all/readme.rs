//! The walk-through's code blocks (the README's and the guide pages', `docs/guide/NN-*.md`) stay
//! what they say they are (issue 23): every fence names its language (```sh: a step of the
//! walk-through that `.ci/readme-run` runs; ```text: a synopsis), the steps call `nsrm` the one way
//! the README installs it (never `cargo run` or `./target/...`), and every flag a step or synopsis
//! passes to `nsrm` is one that command documents in its `--help` (old spellings, kept as hidden
//! aliases, are not used).

use crate::common::nsrm;
use std::collections::{BTreeMap, BTreeSet};

use std::path::Path;

/// The walk-through's pages in the order `.ci/readme-run` runs them: README.md, then the guide
/// pages `docs/guide/NN-*.md` by name; (path relative to the repository, text).
fn pages() -> Vec<(String, String)> {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let mut guide: Vec<String> = std::fs::read_dir(root.join("docs/guide"))
        .expect("docs/guide")
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md") && n.starts_with(|c: char| c.is_ascii_digit()))
        .collect();
    guide.sort();
    assert!(guide.len() >= 8, "the guide pages: {guide:?}");
    std::iter::once("README.md".to_string())
        .chain(guide.into_iter().map(|n| format!("docs/guide/{n}")))
        .map(|p| {
            let text = std::fs::read_to_string(root.join(&p)).unwrap();
            (p, text)
        })
        .collect()
}

/// ("page:line" of the opening fence, language, lines) of every fenced block of every page.
fn blocks() -> Vec<(String, String, Vec<String>)> {
    let mut out = Vec::new();
    for (page, text) in pages() {
        let mut open: Option<(String, String, Vec<String>)> = None;
        for (i, line) in text.lines().enumerate() {
            if let Some(rest) = line.strip_prefix("```") {
                match open.take() {
                    Some(b) => out.push(b),
                    None => {
                        let at = format!("{page}:{}", i + 1);
                        open = Some((at, rest.trim().to_string(), Vec::new()));
                    }
                }
            } else if let Some((_, _, lines)) = open.as_mut() {
                lines.push(line.to_string());
            }
        }
        assert!(open.is_none(), "{page}: an unclosed code fence");
    }
    out
}

#[test]
fn every_block_is_a_step_or_a_synopsis() {
    let mut steps = 0;
    for (line, lang, lines) in blocks() {
        assert!(
            !lang.is_empty(),
            "{line}: a fence without a language (```sh for a step, ```text for a synopsis)"
        );
        if lang == "sh" {
            steps += 1;
            for l in &lines {
                let code = l.split('#').next().unwrap_or("");
                assert!(
                    !code.contains("cargo ") && !code.contains("target/"),
                    "{line}: a step runs `nsrm` as installed, not `{l}`"
                );
                assert!(
                    !code.contains("../shared"),
                    "{line}: steps name the shared data as $NSRM_SHARED: `{l}`"
                );
            }
        }
    }
    assert!(steps >= 6, "only {steps} runnable blocks");
}

/// The `nsrm` subcommand (one or two words) and the `--flags` of each command line in the blocks.
fn commands() -> BTreeMap<String, BTreeSet<String>> {
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (_, lang, lines) in blocks() {
        if lang != "sh" && lang != "text" {
            continue;
        }
        // Join continuation lines of a synopsis (indented under the `nsrm` line).
        let mut joined: Vec<String> = Vec::new();
        for l in &lines {
            let t = l.trim_start();
            if t.starts_with("nsrm ") {
                joined.push(t.to_string());
            } else if l.starts_with(' ') && !joined.is_empty() && !t.starts_with('#') {
                let last = joined.last_mut().unwrap();
                last.push(' ');
                last.push_str(t);
            }
        }
        for l in joined {
            let code = l.split(" #").next().unwrap_or("");
            let words: Vec<&str> = code.split_whitespace().collect();
            let mut sub = words[1].to_string();
            if matches!(sub.as_str(), "chart" | "farm") && words.len() > 2 {
                sub = format!("{sub} {}", words[2]);
            }
            let flags = out.entry(sub).or_default();
            // After a bare `--`, the words are another command's (`farm run -- APPLY'S FLAGS`).
            for w in words.iter().take_while(|w| **w != "--") {
                let w = w.trim_start_matches(['[', '(']);
                if let Some(f) = w.strip_prefix("--") {
                    let f: String = f
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                        .collect();
                    if !f.is_empty() {
                        flags.insert(format!("--{f}"));
                    }
                }
            }
        }
    }
    out
}

#[test]
fn every_flag_in_the_blocks_is_documented_by_its_command() {
    let cmds = commands();
    assert!(
        cmds.contains_key("apply") && cmds.contains_key("chart extract"),
        "{cmds:?}"
    );
    for (sub, flags) in cmds {
        let o = nsrm().args(sub.split(' ')).arg("--help").output().unwrap();
        assert!(o.status.success(), "nsrm {sub} --help");
        let help = String::from_utf8_lossy(&o.stdout);
        for f in flags {
            if f == "--help" {
                continue;
            }
            let documented = help
                .split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                .any(|w| w == f);
            assert!(
                documented,
                "the walk-through: `nsrm {sub} {f}`: not in `nsrm {sub} --help`"
            );
        }
    }
}
