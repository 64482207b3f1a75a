//! The YAML writer of the job descriptions: any `serde::Serialize` value (the typed documents
//! of `jobs.rs` and `resources.rs`, a `serde_json::Value` passed through) as block mappings and
//! sequences in the order serialized, every string double-quoted, so no value is ever read back
//! as another type (`"yes"`, `"1-4"`, `"0777"`), and every character outside YAML's printable
//! set, or one a YAML 1.1 reader takes for a line break (C0 and C1 controls, DEL, U+0085,
//! U+2028, U+2029), the BOM and the non-characters U+FFFE/U+FFFF escaped (`\xNN`, `\uNNNN`), so
//! every string, every path included, reads back exactly, with YAML 1.1 readers (PyYAML, which
//! `openjd` and `deadline` use) as with YAML 1.2 ones (serde_norway, libyaml).
//!
//! Why a writer of its own, and why this shape:
//! - Not serde_norway's (libyaml's) emitter: it picks a style per string and writes a string
//!   with line breaks as a literal block, where a U+0085 or U+2028 is taken as a line break by
//!   a YAML 1.1 reader and comes back as another string; this writer has one style, always
//!   escaped.
//! - The documents are typed structs deriving `Serialize` (field names checked by the compiler,
//!   renamed by serde), and this module is a `serde::Serializer`: a struct's fields come out in
//!   their declared order. Not through `serde_json::Value`: without serde_json's
//!   `preserve_order` its objects sort their keys (a Kubernetes object would start with
//!   `apiVersion`, but a pod's `containers` before `restartPolicy`, and the text would change),
//!   and that feature cannot be turned on for this crate alone: cargo unifies it with the
//!   corrector's serde_json, whose model files' key order would change with it.
//! - The serializer collects a small private tree ([`Tree`]) that the block writer lays out:
//!   a sequence item that is a mapping starts on the dash's line, so the layout needs to know
//!   a value's kind before writing it.
//!
//! Integers are written as integers, finite floats with a `.` and a signed exponent (`1.5`,
//! `1.0e+20`), which YAML 1.1 and 1.2 readers both take as the same number; `null`, unit,
//! bytes, non-finite floats and non-string mapping keys are refused (no job field takes them).

use serde::ser::{self, Serialize};

/// Why a value could not be written as YAML.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Error(String);

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "YAML: {}", self.0)
    }
}

impl std::error::Error for Error {}

impl ser::Error for Error {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        Error(msg.to_string())
    }
}

/// The YAML text of `value` (one document, no `---`).
pub(crate) fn to_string<T: Serialize + ?Sized>(value: &T) -> Result<String, Error> {
    let tree = value.serialize(TreeSerializer)?;
    let mut out = String::new();
    write(&tree, 0, &mut out);
    Ok(out)
}

/// Pairs written as a mapping in their order (keys known only at run time: labels, node
/// selectors, resource names).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Pairs<K, V>(pub Vec<(K, V)>);

impl<K, V> Pairs<K, V> {
    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl<K: Serialize, V: Serialize> Serialize for Pairs<K, V> {
    fn serialize<S: ser::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use ser::SerializeMap;
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

/// A serialized value, before layout.
#[derive(Debug, Clone, PartialEq)]
enum Tree {
    Str(String),
    Int(i128),
    Float(f64),
    Bool(bool),
    Map(Vec<(String, Tree)>),
    List(Vec<Tree>),
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

/// A finite float as both YAML 1.1 (a `.` required, an exponent signed) and YAML 1.2 read it.
fn float(v: f64) -> String {
    // `{:?}` is the shortest text that reads back as `v`: `1.5`, `1e20`, `1e-7`, `-0.0`.
    let s = format!("{v:?}");
    let (mantissa, exp) = match s.split_once('e') {
        Some((m, e)) => (m.to_string(), Some(e)),
        None => (s.clone(), None),
    };
    let mantissa = if mantissa.contains('.') {
        mantissa
    } else {
        format!("{mantissa}.0")
    };
    match exp {
        Some(e) if e.starts_with('-') => format!("{mantissa}e{e}"),
        Some(e) => format!("{mantissa}e+{e}"),
        None => mantissa,
    }
}

fn scalar(n: &Tree) -> Option<String> {
    match n {
        Tree::Str(s) => Some(quote(s)),
        Tree::Int(i) => Some(i.to_string()),
        Tree::Float(v) => Some(float(*v)),
        Tree::Bool(b) => Some(b.to_string()),
        Tree::Map(m) if m.is_empty() => Some("{}".into()),
        Tree::List(l) if l.is_empty() => Some("[]".into()),
        _ => None,
    }
}

fn write(n: &Tree, indent: usize, out: &mut String) {
    let pad = " ".repeat(indent);
    match n {
        Tree::Map(pairs) => {
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
        Tree::List(items) => {
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

fn refused<T>(what: &str) -> Result<T, Error> {
    Err(Error(format!(
        "{what} is not written (no job field takes one)"
    )))
}

/// Serializes a value into a [`Tree`].
struct TreeSerializer;

/// A sequence (or tuple) being serialized; `variant`: the enum variant it is the value of.
struct SeqBuilder {
    items: Vec<Tree>,
    variant: Option<&'static str>,
}

/// A mapping (or struct) being serialized; `key`: the key waiting for its value.
struct MapBuilder {
    pairs: Vec<(String, Tree)>,
    key: Option<String>,
    variant: Option<&'static str>,
}

/// `{variant: value}`, serde's external tagging of an enum's data-carrying variant.
fn tagged(variant: Option<&'static str>, value: Tree) -> Tree {
    match variant {
        Some(v) => Tree::Map(vec![(v.to_string(), value)]),
        None => value,
    }
}

impl ser::Serializer for TreeSerializer {
    type Ok = Tree;
    type Error = Error;
    type SerializeSeq = SeqBuilder;
    type SerializeTuple = SeqBuilder;
    type SerializeTupleStruct = SeqBuilder;
    type SerializeTupleVariant = SeqBuilder;
    type SerializeMap = MapBuilder;
    type SerializeStruct = MapBuilder;
    type SerializeStructVariant = MapBuilder;

    fn serialize_bool(self, v: bool) -> Result<Tree, Error> {
        Ok(Tree::Bool(v))
    }
    fn serialize_i64(self, v: i64) -> Result<Tree, Error> {
        Ok(Tree::Int(v.into()))
    }
    fn serialize_i128(self, v: i128) -> Result<Tree, Error> {
        Ok(Tree::Int(v))
    }
    fn serialize_u64(self, v: u64) -> Result<Tree, Error> {
        Ok(Tree::Int(v.into()))
    }
    fn serialize_u128(self, v: u128) -> Result<Tree, Error> {
        i128::try_from(v)
            .map(Tree::Int)
            .map_err(|_| Error(format!("{v} is too large")))
    }
    fn serialize_i8(self, v: i8) -> Result<Tree, Error> {
        self.serialize_i64(v.into())
    }
    fn serialize_i16(self, v: i16) -> Result<Tree, Error> {
        self.serialize_i64(v.into())
    }
    fn serialize_i32(self, v: i32) -> Result<Tree, Error> {
        self.serialize_i64(v.into())
    }
    fn serialize_u8(self, v: u8) -> Result<Tree, Error> {
        self.serialize_u64(v.into())
    }
    fn serialize_u16(self, v: u16) -> Result<Tree, Error> {
        self.serialize_u64(v.into())
    }
    fn serialize_u32(self, v: u32) -> Result<Tree, Error> {
        self.serialize_u64(v.into())
    }
    fn serialize_f32(self, v: f32) -> Result<Tree, Error> {
        self.serialize_f64(v.into())
    }
    fn serialize_f64(self, v: f64) -> Result<Tree, Error> {
        if v.is_finite() {
            Ok(Tree::Float(v))
        } else {
            refused("a non-finite number")
        }
    }
    fn serialize_char(self, v: char) -> Result<Tree, Error> {
        Ok(Tree::Str(v.to_string()))
    }
    fn serialize_str(self, v: &str) -> Result<Tree, Error> {
        Ok(Tree::Str(v.to_string()))
    }
    fn serialize_bytes(self, _: &[u8]) -> Result<Tree, Error> {
        refused("a byte string")
    }
    fn serialize_none(self) -> Result<Tree, Error> {
        refused("null")
    }
    fn serialize_some<T: Serialize + ?Sized>(self, v: &T) -> Result<Tree, Error> {
        v.serialize(self)
    }
    fn serialize_unit(self) -> Result<Tree, Error> {
        refused("null")
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<Tree, Error> {
        refused("null")
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
    ) -> Result<Tree, Error> {
        Ok(Tree::Str(variant.to_string()))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        v: &T,
    ) -> Result<Tree, Error> {
        v.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        v: &T,
    ) -> Result<Tree, Error> {
        Ok(tagged(Some(variant), v.serialize(self)?))
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<SeqBuilder, Error> {
        Ok(SeqBuilder {
            items: Vec::with_capacity(len.unwrap_or(0)),
            variant: None,
        })
    }
    fn serialize_tuple(self, len: usize) -> Result<SeqBuilder, Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(self, _: &'static str, len: usize) -> Result<SeqBuilder, Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<SeqBuilder, Error> {
        Ok(SeqBuilder {
            items: Vec::with_capacity(len),
            variant: Some(variant),
        })
    }
    fn serialize_map(self, len: Option<usize>) -> Result<MapBuilder, Error> {
        Ok(MapBuilder {
            pairs: Vec::with_capacity(len.unwrap_or(0)),
            key: None,
            variant: None,
        })
    }
    fn serialize_struct(self, _: &'static str, len: usize) -> Result<MapBuilder, Error> {
        self.serialize_map(Some(len))
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<MapBuilder, Error> {
        Ok(MapBuilder {
            pairs: Vec::with_capacity(len),
            key: None,
            variant: Some(variant),
        })
    }
}

impl SeqBuilder {
    fn push<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        self.items.push(v.serialize(TreeSerializer)?);
        Ok(())
    }
    fn done(self) -> Result<Tree, Error> {
        Ok(tagged(self.variant, Tree::List(self.items)))
    }
}

impl ser::SerializeSeq for SeqBuilder {
    type Ok = Tree;
    type Error = Error;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        self.push(v)
    }
    fn end(self) -> Result<Tree, Error> {
        self.done()
    }
}

impl ser::SerializeTuple for SeqBuilder {
    type Ok = Tree;
    type Error = Error;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        self.push(v)
    }
    fn end(self) -> Result<Tree, Error> {
        self.done()
    }
}

impl ser::SerializeTupleStruct for SeqBuilder {
    type Ok = Tree;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        self.push(v)
    }
    fn end(self) -> Result<Tree, Error> {
        self.done()
    }
}

impl ser::SerializeTupleVariant for SeqBuilder {
    type Ok = Tree;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        self.push(v)
    }
    fn end(self) -> Result<Tree, Error> {
        self.done()
    }
}

impl MapBuilder {
    fn entry<T: Serialize + ?Sized>(&mut self, k: String, v: &T) -> Result<(), Error> {
        let v = v.serialize(TreeSerializer)?;
        self.pairs.push((k, v));
        Ok(())
    }
    fn done(self) -> Result<Tree, Error> {
        Ok(tagged(self.variant, Tree::Map(self.pairs)))
    }
}

impl ser::SerializeMap for MapBuilder {
    type Ok = Tree;
    type Error = Error;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, k: &T) -> Result<(), Error> {
        match k.serialize(TreeSerializer)? {
            Tree::Str(s) => {
                self.key = Some(s);
                Ok(())
            }
            _ => refused("a key that is not a string"),
        }
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        let k = self
            .key
            .take()
            .ok_or_else(|| Error("a value without its key".into()))?;
        self.entry(k, v)
    }
    fn end(self) -> Result<Tree, Error> {
        self.done()
    }
}

impl ser::SerializeStruct for MapBuilder {
    type Ok = Tree;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        k: &'static str,
        v: &T,
    ) -> Result<(), Error> {
        self.entry(k.to_string(), v)
    }
    fn end(self) -> Result<Tree, Error> {
        self.done()
    }
}

impl ser::SerializeStructVariant for MapBuilder {
    type Ok = Tree;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        k: &'static str,
        v: &T,
    ) -> Result<(), Error> {
        self.entry(k.to_string(), v)
    }
    fn end(self) -> Result<Tree, Error> {
        self.done()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn nested_blocks_are_indented_and_strings_quoted() {
        let doc = Pairs(vec![
            ("name", json!("a: b")),
            ("count", json!(3)),
            (
                "steps",
                json!([{"name": "x", "args": ["1", "yes"]}, "plain"]),
            ),
            ("empty", json!([])),
            ("odd key", json!(true)),
        ]);
        // (`json!`'s objects sort their keys: `args` before `name`.)
        let want = "name: \"a: b\"\ncount: 3\nsteps:\n  - args:\n      - \"1\"\n      - \"yes\"\n    name: \"x\"\n  - \"plain\"\nempty: []\n\"odd key\": true\n";
        assert_eq!(to_string(&doc).unwrap(), want);
    }

    /// A struct's fields come out in their declared order, renamed, `None`s skipped; enums as
    /// serde tags them.
    #[test]
    fn typed_values_keep_their_field_order() {
        #[derive(serde::Serialize)]
        #[serde(rename_all = "camelCase")]
        struct Doc {
            z_last_first: u8,
            #[serde(skip_serializing_if = "Option::is_none")]
            gone: Option<u8>,
            a_map: Pairs<String, i64>,
            kinds: Vec<Kind>,
        }
        #[derive(serde::Serialize)]
        enum Kind {
            Unit,
            New(u8),
            Tuple(u8, u8),
            Fields { x: bool },
        }
        let doc = Doc {
            z_last_first: 1,
            gone: None,
            a_map: Pairs(vec![("b".into(), -1), ("a".into(), 2)]),
            kinds: vec![
                Kind::Unit,
                Kind::New(3),
                Kind::Tuple(4, 5),
                Kind::Fields { x: false },
            ],
        };
        let want = "zLastFirst: 1\naMap:\n  b: -1\n  a: 2\nkinds:\n  - \"Unit\"\n  - New: 3\n  - Tuple:\n      - 4\n      - 5\n  - Fields:\n      x: false\n";
        assert_eq!(to_string(&doc).unwrap(), want);
    }

    #[test]
    fn what_no_job_field_takes_is_refused() {
        assert!(to_string(&json!({"a": null})).is_err());
        assert!(to_string(&Some(f64::NAN)).is_err());
        assert!(to_string(&f64::INFINITY).is_err());
        assert!(to_string(&Pairs(vec![(1, 2)])).is_err());
        assert!(to_string(&()).is_err());
    }

    #[test]
    fn control_characters_and_quotes_are_escaped() {
        let s = to_string(&Pairs(vec![("k", "a\"b\\c\nd\te")])).unwrap();
        assert_eq!(s, "k: \"a\\\"b\\\\c\\nd\\te\"\n");
        let s = to_string("\u{0}\u{1b}\u{7f}\u{85}\u{9f}\u{a0}\u{2028}\u{feff}\u{fffe}é").unwrap();
        assert_eq!(
            s,
            "\"\\x00\\x1B\\x7F\\x85\\x9F\u{a0}\\u2028\\uFEFF\\uFFFE\u{e9}\"\n"
        );
    }

    /// Floats are written with a `.` and a signed exponent (YAML 1.1's float form, which YAML
    /// 1.2 reads too) and read back as the same number.
    #[test]
    fn floats_read_back_as_the_same_number() {
        let yaml11 = |t: &str| {
            let t = t.strip_prefix('-').unwrap_or(t);
            let (m, e) = t.split_once('e').unwrap_or((t, ""));
            let (int, frac) = m.split_once('.').expect(t);
            !int.is_empty()
                && int.bytes().all(|b| b.is_ascii_digit())
                && frac.bytes().all(|b| b.is_ascii_digit())
                && (e.is_empty()
                    || (e.len() > 1
                        && e.starts_with(['+', '-'])
                        && e[1..].bytes().all(|b| b.is_ascii_digit())))
        };
        for v in [
            0.0,
            -0.0,
            1.0,
            1.5,
            0.1,
            1e12,
            1e20,
            1e-7,
            -2.5e-300,
            1e300,
            f64::MIN_POSITIVE,
            f64::MAX,
            123_456.789,
        ] {
            let text = to_string(&Pairs(vec![("v", v)])).unwrap();
            let t = text.trim_start_matches("v: ").trim_end();
            assert!(yaml11(t), "{v}: {t}");
            let back: std::collections::BTreeMap<String, f64> =
                serde_norway::from_str(&text).unwrap();
            assert_eq!(back["v"].to_bits(), v.to_bits(), "{v}: {text}");
        }
        assert_eq!(float(1e20), "1.0e+20");
        assert_eq!(float(1e-7), "1.0e-7");
    }

    /// Every string reads back exactly (serde_norway, a YAML 1.2 reader), as a value and as
    /// a key, whatever characters it holds.
    #[test]
    fn every_string_round_trips() {
        use proptest::prelude::*;
        let check = |v: &str| {
            let doc = Pairs(vec![
                ("k", json!(v)),
                ("l", json!([v])),
                (
                    "m",
                    Pairs(vec![(v, 1)])
                        .serialize(serde_json::value::Serializer)
                        .unwrap(),
                ),
            ]);
            let text = to_string(&doc).map_err(|e| e.to_string())?;
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
