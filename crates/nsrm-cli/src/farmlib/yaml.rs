//! A small YAML writer for the job descriptions: block mappings and sequences in the order
//! built, every string double-quoted, so no value is ever read back as another type (`"yes"`,
//! `"1-4"`, `"0777"`), and every character outside YAML's printable set, or one a YAML 1.1
//! reader takes for a line break (C0 and C1 controls, DEL, U+0085, U+2028, U+2029), the BOM and
//! the non-characters U+FFFE/U+FFFF escaped (`\xNN`, `\uNNNN`), so every string, every path
//! included, reads back exactly, with YAML 1.1 readers (PyYAML, which `openjd` and `deadline`
//! use) as with YAML 1.2 ones (serde_norway, libyaml).
//!
//! Not serde_norway's (libyaml's) emitter: it picks a style per string and writes a string
//! with line breaks as a literal block, where a U+0085 or U+2028 is taken as a line break by a
//! YAML 1.1 reader and comes back as another string; this writer has one style, always escaped.

/// A YAML value.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Node {
    Str(String),
    Int(i64),
    Bool(bool),
    Map(Vec<(String, Node)>),
    List(Vec<Node>),
}

impl Node {
    /// A mapping from `(key, value)` pairs, in order.
    pub(crate) fn map<K: Into<String>>(pairs: impl IntoIterator<Item = (K, Node)>) -> Node {
        Node::Map(pairs.into_iter().map(|(k, v)| (k.into(), v)).collect())
    }

    /// A string.
    pub(crate) fn str(s: impl Into<String>) -> Node {
        Node::Str(s.into())
    }

    /// A sequence of strings.
    pub(crate) fn strs<S: Into<String>>(items: impl IntoIterator<Item = S>) -> Node {
        Node::List(items.into_iter().map(|s| Node::Str(s.into())).collect())
    }
}

/// Whether `c` stands for itself inside a double-quoted scalar for every YAML reader.
fn plain_char(c: char) -> bool {
    matches!(c as u32, 0x20..=0x7E | 0xA0..=0x2027 | 0x202A..=0xD7FF | 0xE000..=0xFEFE | 0xFF00..=0xFFFD | 0x10000..=0x10FFFF)
}

fn quote(s: &str) -> String {
    use std::fmt::Write;
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if plain_char(c) => out.push(c),
            c if (c as u32) <= 0xFF => {
                let _ = write!(out, "\\x{:02X}", c as u32);
            }
            c if (c as u32) <= 0xFFFF => {
                let _ = write!(out, "\\u{:04X}", c as u32);
            }
            c => {
                let _ = write!(out, "\\U{:08X}", c as u32);
            }
        }
    }
    out.push('"');
    out
}

fn key(k: &str) -> String {
    let plain = k
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && k.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '/' | '-'));
    if plain {
        k.to_string()
    } else {
        quote(k)
    }
}

fn scalar(n: &Node) -> Option<String> {
    match n {
        Node::Str(s) => Some(quote(s)),
        Node::Int(i) => Some(i.to_string()),
        Node::Bool(b) => Some(b.to_string()),
        Node::Map(m) if m.is_empty() => Some("{}".into()),
        Node::List(l) if l.is_empty() => Some("[]".into()),
        _ => None,
    }
}

fn write(n: &Node, indent: usize, out: &mut String) {
    let pad = " ".repeat(indent);
    match n {
        Node::Map(pairs) => {
            for (k, v) in pairs {
                out.push_str(&pad);
                out.push_str(&key(k));
                out.push(':');
                match scalar(v) {
                    Some(s) => {
                        out.push(' ');
                        out.push_str(&s);
                        out.push('\n');
                    }
                    None => {
                        out.push('\n');
                        // Sequences under a key are indented like the key's children.
                        write(v, indent + 2, out);
                    }
                }
            }
        }
        Node::List(items) => {
            for item in items {
                out.push_str(&pad);
                out.push_str("- ");
                match scalar(item) {
                    Some(s) => {
                        out.push_str(&s);
                        out.push('\n');
                    }
                    None => {
                        // The item's first line follows the dash; the rest align with it.
                        let mut inner = String::new();
                        write(item, indent + 2, &mut inner);
                        out.push_str(inner.trim_start_matches(' '));
                    }
                }
            }
        }
        other => {
            out.push_str(&pad);
            out.push_str(&scalar(other).unwrap_or_default());
            out.push('\n');
        }
    }
}

/// The YAML text of `n` (one document, no `---`).
pub(crate) fn to_string(n: &Node) -> String {
    let mut out = String::new();
    write(n, 0, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_blocks_are_indented_and_strings_quoted() {
        let doc = Node::map([
            ("name", Node::str("a: b")),
            ("count", Node::Int(3)),
            (
                "steps",
                Node::List(vec![
                    Node::map([("name", Node::str("x")), ("args", Node::strs(["1", "yes"]))]),
                    Node::str("plain"),
                ]),
            ),
            ("empty", Node::List(vec![])),
            ("odd key", Node::Bool(true)),
        ]);
        let want = "name: \"a: b\"\ncount: 3\nsteps:\n  - name: \"x\"\n    args:\n      - \"1\"\n      - \"yes\"\n  - \"plain\"\nempty: []\n\"odd key\": true\n";
        assert_eq!(to_string(&doc), want);
    }

    #[test]
    fn control_characters_and_quotes_are_escaped() {
        let s = to_string(&Node::map([("k", Node::str("a\"b\\c\nd\te"))]));
        assert_eq!(s, "k: \"a\\\"b\\\\c\\nd\\te\"\n");
        let s = to_string(&Node::str(
            "\u{0}\u{1b}\u{7f}\u{85}\u{9f}\u{a0}\u{2028}\u{feff}\u{fffe}é",
        ));
        assert_eq!(
            s,
            "\"\\x00\\x1B\\x7F\\x85\\x9F\u{a0}\\u2028\\uFEFF\\uFFFE\u{e9}\"\n"
        );
    }

    /// Every string reads back exactly (serde_norway, a YAML 1.2 reader), as a value and as
    /// a key, whatever characters it holds.
    #[test]
    fn every_string_round_trips() {
        use proptest::prelude::*;
        let check = |v: &str| {
            let doc = Node::map([
                ("k", Node::str(v)),
                ("l", Node::strs([v])),
                ("m", Node::Map(vec![(v.to_string(), Node::Int(1))])),
            ]);
            let text = to_string(&doc);
            let back: std::collections::BTreeMap<String, serde_norway::Value> =
                serde_norway::from_str(&text).map_err(|e| format!("{e}: {text}"))?;
            let want = serde_norway::Value::String(v.to_string());
            if back.get("k") != Some(&want)
                || back.get("l") != Some(&serde_norway::Value::Sequence(vec![want]))
                || back.get("m").and_then(|m| m.get(v))
                    != Some(&serde_norway::Value::Number(1.into()))
            {
                return Err(format!("{v:?} came back as {back:?} from {text}"));
            }
            Ok(())
        };
        // Every character of the first planes one by one (not surrogates: no `char`).
        for c in (0u32..0x3_0000).filter_map(char::from_u32) {
            check(&format!("a{c}b")).unwrap();
        }
        proptest!(ProptestConfig::with_cases(2000), |(v in any::<String>())| {
            prop_assert!(check(&v).is_ok(), "{}", check(&v).unwrap_err());
        });
    }
}
