//! A small YAML writer for the job descriptions: block mappings and sequences in the order
//! built, every string double-quoted with JSON's escapes (a subset of YAML's double-quoted
//! style), so no value is ever read back as another type (`"yes"`, `"1-4"`, `"0777"`).

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

fn quote(s: &str) -> String {
    // serde_json's string escaping is valid inside a YAML double-quoted scalar.
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".to_string())
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
    }
}
