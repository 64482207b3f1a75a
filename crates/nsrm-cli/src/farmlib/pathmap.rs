//! Path mapping: a path as the submitting machine names it, rewritten to where a worker mounts
//! it. The rules are Open Job Description's (`pathmapping-1.0`: a source path format, a source
//! path and a destination path); `FROM=TO` pairs give POSIX rules. A path is mapped by the rule
//! with the longest source path that is a whole-component prefix of it; a path no rule covers
//! is kept as it is.

use super::{read_bounded, FarmError};
use serde::Deserialize;

/// How the source paths of a rule are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub(crate) enum SourceFormat {
    /// `/`-separated, case-sensitive.
    Posix,
    /// `\` or `/`-separated, case-insensitive, a drive letter or UNC prefix.
    Windows,
}

/// One rule: paths under `source` go under `destination` (the worker's, `/`-separated).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub(crate) struct Rule {
    pub source_path_format: SourceFormat,
    pub source_path: String,
    pub destination_path: String,
}

/// A set of rules.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct PathMap {
    rules: Vec<Rule>,
}

#[derive(Deserialize)]
struct RulesFile {
    #[serde(default)]
    version: Option<String>,
    #[serde(default)]
    path_mapping_rules: Vec<Rule>,
}

fn components(s: &str, format: SourceFormat) -> Vec<String> {
    let parts: Vec<&str> = match format {
        SourceFormat::Posix => s.split('/').collect(),
        SourceFormat::Windows => s.split(['/', '\\']).collect(),
    };
    parts
        .into_iter()
        .filter(|p| !p.is_empty() && *p != ".")
        .map(|p| match format {
            SourceFormat::Posix => p.to_string(),
            SourceFormat::Windows => p.to_lowercase(),
        })
        .collect()
}

impl PathMap {
    /// No rules: every path is kept.
    pub(crate) fn new() -> PathMap {
        PathMap::default()
    }

    /// Whether there are no rules.
    pub(crate) fn is_empty(&self) -> bool {
        self.rules.is_empty()
    }

    /// Adds a POSIX rule from `FROM=TO` (both absolute).
    pub(crate) fn add_pair(&mut self, spec: &str) -> Result<(), FarmError> {
        let bad = |why: &str| FarmError::Usage(format!("path mapping `{spec}`: {why}"));
        let (from, to) = spec
            .split_once('=')
            .ok_or_else(|| bad("expected FROM=TO, e.g. /mnt/projects=/shared/projects"))?;
        if !from.starts_with('/') || !to.starts_with('/') {
            return Err(bad("both paths must be absolute"));
        }
        self.add(Rule {
            source_path_format: SourceFormat::Posix,
            source_path: from.to_string(),
            destination_path: to.to_string(),
        })
    }

    /// Adds a rule.
    pub(crate) fn add(&mut self, rule: Rule) -> Result<(), FarmError> {
        if components(&rule.source_path, rule.source_path_format).is_empty() {
            return Err(FarmError::Usage(format!(
                "path mapping from `{}`: the source path must name a directory below the root",
                rule.source_path
            )));
        }
        if rule.destination_path.is_empty() || rule.destination_path.contains('\0') {
            return Err(FarmError::Usage(format!(
                "path mapping to `{}`: not a usable destination path",
                rule.destination_path
            )));
        }
        self.rules.push(rule);
        Ok(())
    }

    /// Adds the rules of an Open Job Description path-mapping file (`pathmapping-1.0` JSON, as
    /// a session's `PathMappingRulesFile`). An empty file holds no rules.
    pub(crate) fn add_openjd_file(&mut self, path: &std::path::Path) -> Result<(), FarmError> {
        let bytes = read_bounded(path, 16 << 20)?;
        if bytes.iter().all(u8::is_ascii_whitespace) {
            return Ok(());
        }
        let bad = |why: String| FarmError::Format {
            path: path.to_path_buf(),
            why,
        };
        let file: RulesFile =
            serde_json::from_slice(&bytes).map_err(|e| bad(format!("path mapping rules: {e}")))?;
        // A session without rules may write a file with no version.
        if file.version.as_deref() != Some("pathmapping-1.0") && !file.path_mapping_rules.is_empty()
        {
            return Err(bad(format!(
                "path mapping rules of version `{}`; `pathmapping-1.0` is understood",
                file.version.as_deref().unwrap_or("(none)")
            )));
        }
        for r in file.path_mapping_rules {
            self.add(r)?;
        }
        Ok(())
    }

    /// `p` as the worker names it.
    pub(crate) fn map(&self, p: &str) -> String {
        let mut best: Option<(usize, &Rule, Vec<&str>)> = None;
        for r in &self.rules {
            let src = components(&r.source_path, r.source_path_format);
            let raw: Vec<&str> = match r.source_path_format {
                SourceFormat::Posix => p.split('/').collect(),
                SourceFormat::Windows => p.split(['/', '\\']).collect(),
            };
            let raw: Vec<&str> = raw
                .into_iter()
                .filter(|c| !c.is_empty() && *c != ".")
                .collect();
            let absolute = match r.source_path_format {
                SourceFormat::Posix => p.starts_with('/'),
                SourceFormat::Windows => true,
            };
            if !absolute || raw.len() < src.len() {
                continue;
            }
            let matches = src
                .iter()
                .zip(&raw)
                .all(|(a, b)| match r.source_path_format {
                    SourceFormat::Posix => a == b,
                    SourceFormat::Windows => *a == b.to_lowercase(),
                });
            if matches && best.as_ref().is_none_or(|(n, _, _)| src.len() > *n) {
                best = Some((src.len(), r, raw[src.len()..].to_vec()));
            }
        }
        match best {
            None => p.to_string(),
            Some((_, r, rest)) => {
                let mut out = r.destination_path.trim_end_matches('/').to_string();
                if out.is_empty() {
                    out.push('/');
                }
                for c in rest {
                    if !out.ends_with('/') {
                        out.push('/');
                    }
                    out.push_str(c);
                }
                out
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_longest_whole_component_prefix_wins() {
        let mut m = PathMap::new();
        m.add_pair("/mnt/proj=/data").unwrap();
        m.add_pair("/mnt/proj/shots=/fast/shots").unwrap();
        assert_eq!(m.map("/mnt/proj/a/b.exr"), "/data/a/b.exr");
        assert_eq!(m.map("/mnt/proj/shots/s1.exr"), "/fast/shots/s1.exr");
        // Not a whole component: kept.
        assert_eq!(m.map("/mnt/projects/x.exr"), "/mnt/projects/x.exr");
        assert_eq!(m.map("relative/x.exr"), "relative/x.exr");
        assert_eq!(m.map("/mnt/proj"), "/data");
    }

    #[test]
    fn openjd_rules_files_are_read_and_windows_sources_match_any_case() {
        let dir = std::env::temp_dir().join(format!("nsrm-pathmap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("rules.json");
        std::fs::write(
            &f,
            r#"{"version": "pathmapping-1.0", "path_mapping_rules": [
                {"source_path_format": "WINDOWS", "source_path": "Z:\\Projects", "destination_path": "/mnt/projects"}]}"#,
        )
        .unwrap();
        let mut m = PathMap::new();
        m.add_openjd_file(&f).unwrap();
        assert_eq!(m.map(r"z:\projects\show\a.exr"), "/mnt/projects/show/a.exr");
        std::fs::write(&f, "").unwrap();
        let mut empty = PathMap::new();
        empty.add_openjd_file(&f).unwrap();
        assert!(empty.is_empty());
        std::fs::write(&f, "{}").unwrap();
        let mut empty = PathMap::new();
        empty.add_openjd_file(&f).unwrap();
        assert!(empty.is_empty());
        std::fs::write(
            &f,
            r#"{"version": "pathmapping-9", "path_mapping_rules": [
                {"source_path_format": "POSIX", "source_path": "/a", "destination_path": "/b"}]}"#,
        )
        .unwrap();
        assert!(PathMap::new().add_openjd_file(&f).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn malformed_pairs_are_usage_errors() {
        for bad in ["nothing", "rel=/a", "/a=rel", "/=/a"] {
            let e = PathMap::new().add_pair(bad).unwrap_err();
            assert!(e.is_usage(), "{bad}: {e}");
        }
    }
}
