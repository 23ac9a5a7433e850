//! Strict TOML input files (instrument configs, plans, simulator configs): parse,
//! validate whole, and report the first fault as `FILE:LINE:COL: field `NAME`: why`.
//!
//! Validation functions name a fault by its dotted field path (`motion.axes[1].max`);
//! [`span_of`] turns that path back into the place in the text, so that every input
//! error points at the line to fix. Errors of the TOML reader itself get their field
//! the other way round: [`field_at`] finds the path of the value the error is about.
//!
//! Internally tagged enums (`kind = "…"` and the variant's fields in one table) are
//! read with [`Tagged`] rather than `#[serde(tag = "kind")]`, whose buffering loses
//! the field and the place of every error inside the table.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserializer;
use serde::de::{self, DeserializeOwned, DeserializeSeed, IntoDeserializer, MapAccess, Visitor};
use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// An input file that could not be used, with where and why.
#[derive(Clone, Debug, PartialEq)]
pub struct FileError {
    /// What kind of file (`instrument config`, `plan`), for an unnamed text.
    pub kind: &'static str,
    /// The file, when known.
    pub path: Option<PathBuf>,
    /// 1-based line, when the fault has a place.
    pub line: Option<usize>,
    /// 1-based column, when the fault has a place.
    pub column: Option<usize>,
    /// The field at fault (`motion.axes[1].max`), when there is one.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl FileError {
    /// A fault with the file as a whole (unreadable, missing).
    pub fn whole(kind: &'static str, path: Option<&Path>, message: impl Into<String>) -> Self {
        FileError {
            kind,
            path: path.map(Path::to_path_buf),
            line: None,
            column: None,
            field: None,
            message: message.into(),
        }
    }

    /// A fault on 1-based `line`, at `field` when there is one.
    pub fn at_line(
        kind: &'static str,
        path: Option<&Path>,
        line: usize,
        field: Option<&str>,
        message: impl Into<String>,
    ) -> Self {
        let mut e = Self::whole(kind, path, message);
        e.line = Some(line);
        e.field = field.map(str::to_string);
        e
    }

    /// A fault at `field` of `text`, located by [`span_of`].
    pub fn at_field(
        kind: &'static str,
        path: Option<&Path>,
        text: &str,
        field: String,
        message: impl Into<String>,
    ) -> Self {
        let text = crate::text::strip_bom(text);
        let mut e = Self::whole(kind, path, message);
        if let Some(s) = span_of(text, &field) {
            let (l, c) = crate::text::line_col(text, s.start);
            e.line = Some(l);
            e.column = Some(c);
        }
        e.field = Some(field);
        e
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unnamed = format!("<{}>", self.kind);
        crate::text::write_located(
            f,
            self.path.as_deref(),
            &unnamed,
            self.line,
            self.column,
            self.field.as_deref(),
            &self.message,
        )
    }
}

impl std::error::Error for FileError {}

/// Parses `text` as a `T` (unknown keys are errors when `T` denies them), then runs
/// `validate`, whose `Err((field, message))` is located in the text. `path` only
/// labels errors. A leading byte order mark is ignored.
pub fn parse<T: DeserializeOwned>(
    kind: &'static str,
    text: &str,
    path: Option<&Path>,
    validate: impl FnOnce(&T) -> Result<(), (String, String)>,
) -> Result<T, FileError> {
    let text = crate::text::strip_bom(text);
    let value: T = toml::from_str(text).map_err(|e| {
        let fault = Fault::of(text, &e);
        let mut err = FileError::whole(kind, path, fault.message);
        if let Some(s) = fault.span {
            let (l, c) = crate::text::line_col(text, s.start);
            err.line = Some(l);
            err.column = Some(c);
        }
        err.field = fault.field;
        err
    })?;
    validate(&value)
        .map_err(|(field, message)| FileError::at_field(kind, path, text, field, message))?;
    Ok(value)
}

/// A TOML reader's error, placed: the span to report, the field it concerns and
/// the message without the field.
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    /// Where in the text, when known.
    pub span: Option<Range<usize>>,
    /// The dotted path of the field at fault (`points.theta_o`), when the error is
    /// about a value rather than the document as a whole.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl Fault {
    /// Places `e`, an error of `toml::from_str(text)`.
    ///
    /// The reader reports a span and a message. The field is the value at that span
    /// ([`field_at`]), followed by the fields named by `field `NAME`: ` prefixes that
    /// [`Tagged`] puts on errors from inside a tagged table (the reader can only
    /// point at the whole table then); the span is then moved to that field.
    pub fn of(text: &str, e: &toml::de::Error) -> Fault {
        let mut message = e.message().trim();
        let mut span = e.span().map(|s| refine(text, s, message));
        // An unknown key's message names it, and its span is the key, not a value.
        let mut field = span
            .as_ref()
            .filter(|_| !message.starts_with("unknown field `"))
            .and_then(|s| field_at(text, s));
        let mut inner = Vec::new();
        while let Some((name, rest)) = message
            .strip_prefix("field `")
            .and_then(|r| r.split_once("`: "))
        {
            inner.push(name);
            message = rest;
        }
        if !inner.is_empty() {
            let path = field.into_iter().chain(inner.iter().map(|s| s.to_string()));
            let path = path.collect::<Vec<_>>().join(".");
            span = span_of(text, &path).or(span);
            field = Some(path);
        }
        Fault {
            span,
            field,
            message: message.to_string(),
        }
    }
}

/// Narrows an error's span from a whole table to the offending key, where the
/// message names one (`unknown field `speed``): tagged enums make the TOML parser
/// report the table rather than the key.
fn refine(text: &str, span: Range<usize>, message: &str) -> Range<usize> {
    let Some(rest) = message.strip_prefix("unknown field `") else {
        return span;
    };
    let Some(key) = rest.split('`').next() else {
        return span;
    };
    // The span may be just the table's header: search its body, up to the next header.
    let region = text.get(span.start..).unwrap_or("");
    let mut offset = span.start;
    for (k, line) in region.split_inclusive('\n').enumerate() {
        let trimmed = line.trim_start();
        if k > 0 && trimmed.starts_with('[') {
            break;
        }
        if let Some(after) = trimmed.strip_prefix(key)
            && after.trim_start().starts_with('=')
        {
            let at = offset + (line.len() - trimmed.len());
            return at..at + key.len();
        }
        offset += line.len();
    }
    span
}

/// Reads the file at `path` and [`parse`]s it; also returns the text (run files keep
/// configs verbatim). Only a regular file of at most
/// [`MAX_CONFIG_BYTES`](crate::input::MAX_CONFIG_BYTES) is read ([`read`]).
pub fn load<T: DeserializeOwned>(
    kind: &'static str,
    path: &Path,
    validate: impl FnOnce(&T) -> Result<(), (String, String)>,
) -> Result<(T, String), FileError> {
    let text = read(kind, path)?;
    let value = parse(kind, &text, Some(path), validate)?;
    Ok((value, text))
}

/// The text of the TOML file at `path` of the given `kind`, read through
/// [`crate::input::read_text`]: a regular file of at most
/// [`MAX_CONFIG_BYTES`](crate::input::MAX_CONFIG_BYTES) of UTF-8; a FIFO, a device or
/// a directory is refused without being read.
pub fn read(kind: &'static str, path: &Path) -> Result<String, FileError> {
    crate::input::read_text(path, crate::input::MAX_CONFIG_BYTES)
        .map_err(|e| FileError::whole(kind, Some(path), e.reason()))
}

/// The dotted path (`motion.axes[1].max`) of the value whose span is exactly `span`
/// in a TOML document, the innermost one if several are; `None` for the document
/// itself, a span no value has, or text that is not TOML.
pub fn field_at(text: &str, span: &Range<usize>) -> Option<String> {
    let doc: Spanned<DeTable> = DeTable::parse(text).ok()?;
    let mut path = String::new();
    find_table(doc.get_ref(), span, &mut path).then_some(path)
}

/// Appends to `path` the way through `table` to the value at `span`; false (with
/// `path` as it was) when there is none.
fn find_table(table: &DeTable, span: &Range<usize>, path: &mut String) -> bool {
    let len = path.len();
    for (k, v) in table.iter() {
        if !path.is_empty() {
            path.push('.');
        }
        path.push_str(k.get_ref());
        if find_value(v, span, path) {
            return true;
        }
        path.truncate(len);
    }
    false
}

fn find_value(v: &Spanned<DeValue>, span: &Range<usize>, path: &mut String) -> bool {
    let inner = match v.get_ref() {
        DeValue::Table(t) => find_table(t, span, path),
        DeValue::Array(a) => {
            let len = path.len();
            let mut found = false;
            for (i, item) in a.iter().enumerate() {
                path.push_str(&format!("[{i}]"));
                if find_value(item, span, path) {
                    found = true;
                    break;
                }
                path.truncate(len);
            }
            found
        }
        _ => false,
    };
    inner || v.span() == *span
}

/// The byte range of the value at a dotted `path` (`motion.axes[1].max`) in a TOML
/// document: the deepest part of the path that exists (the whole document if none
/// does), `None` if the text is not TOML.
pub fn span_of(text: &str, path: &str) -> Option<Range<usize>> {
    let doc: Spanned<DeTable> = DeTable::parse(text).ok()?;
    let mut span = doc.span();
    let mut table: Option<&DeTable> = Some(doc.get_ref());
    let mut value: Option<&Spanned<DeValue>> = None;
    for part in path.split('.') {
        let (key, index) = match part.find('[') {
            Some(b) => (
                &part[..b],
                part[b + 1..part.len().saturating_sub(1).max(b + 1)]
                    .parse::<usize>()
                    .ok(),
            ),
            None => (part, None),
        };
        let t = match value {
            Some(v) => match v.get_ref() {
                DeValue::Table(t) => t,
                _ => return Some(span),
            },
            None => table?,
        };
        let Some((_, v)) = t.iter().find(|(k, _)| k.get_ref().as_ref() == key) else {
            return Some(span);
        };
        span = v.span();
        value = Some(v);
        table = None;
        if let (Some(i), DeValue::Array(a)) = (index, v.get_ref())
            && let Some(item) = a.get(i)
        {
            span = item.span();
            value = Some(item);
        }
    }
    Some(span)
}

/// The table of an internally tagged enum: its `kind` and the variant's fields, to be
/// read by a hand-written `Deserialize` that keeps each error's field:
///
/// ```
/// use gonio_core::tomlfile::Tagged;
/// use serde::{Deserialize, Deserializer};
///
/// #[derive(Debug, PartialEq, Deserialize)]
/// #[serde(deny_unknown_fields)]
/// struct Disc {
///     radius: f64,
/// }
/// #[derive(Debug, PartialEq)]
/// enum Shape {
///     Disc(Disc),
/// }
/// impl<'de> Deserialize<'de> for Shape {
///     fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
///         let t = Tagged::read(d, &["disc"])?;
///         match t.kind() {
///             "disc" => t.fields().map(Shape::Disc),
///             _ => Err(t.unknown_kind()),
///         }
///     }
/// }
/// #[derive(Debug, Deserialize)]
/// struct Doc {
///     shape: Shape,
/// }
/// let e = gonio_core::tomlfile::parse::<Doc>(
///     "shape", "[shape]\nkind = \"disc\"\nradius = \"big\"\n", None, |_| Ok(()),
/// )
/// .unwrap_err();
/// assert_eq!(e.to_string(), "<shape>:3:10: field `shape.radius`: invalid type: string \"big\", expected f64");
/// ```
///
/// Errors from inside the table start `field `NAME`: `, which [`parse`] (through
/// [`Fault::of`]) turns into the field's full path and place.
#[derive(Clone, Debug)]
pub struct Tagged {
    kind: String,
    fields: toml::Table,
    kinds: &'static [&'static str],
}

impl Tagged {
    /// Reads the table; `kinds` are the accepted values of `kind`, for messages.
    pub fn read<'de, D: Deserializer<'de>>(
        deserializer: D,
        kinds: &'static [&'static str],
    ) -> Result<Tagged, D::Error> {
        deserializer.deserialize_map(TaggedVisitor { kinds })
    }

    /// The value of `kind`.
    pub fn kind(&self) -> &str {
        &self.kind
    }

    /// The variant's fields (every key but `kind`) as a `T`; an error in a field's
    /// value names the field.
    pub fn fields<T: DeserializeOwned, E: de::Error>(self) -> Result<T, E> {
        let access = Fields {
            iter: self.fields.into_iter(),
            value: None,
        };
        T::deserialize(de::value::MapAccessDeserializer::new(access))
            .map_err(|e: toml::de::Error| E::custom(e.message()))
    }

    /// The error for a `kind` that is none of the accepted ones.
    pub fn unknown_kind<E: de::Error>(&self) -> E {
        E::custom(format!(
            "field `kind`: unknown kind {:?}, expected {}",
            self.kind,
            one_of(self.kinds)
        ))
    }
}

/// `"a"`, `"a" or "b"`, `one of "a", "b" or "c"`.
fn one_of(kinds: &[&str]) -> String {
    let q: Vec<String> = kinds.iter().map(|k| format!("{k:?}")).collect();
    match q.as_slice() {
        [] => "nothing".into(),
        [one] => one.clone(),
        [init @ .., last] => format!("one of {} or {last}", init.join(", ")),
    }
}

struct TaggedVisitor {
    kinds: &'static [&'static str],
}

impl<'de> Visitor<'de> for TaggedVisitor {
    type Value = Tagged;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "a table with kind = {}", one_of(self.kinds))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Tagged, A::Error> {
        let mut kind = None;
        let mut fields = toml::Table::new();
        while let Some(key) = map.next_key::<String>()? {
            if key == "kind" {
                kind = Some(map.next_value::<String>()?);
            } else {
                let value: toml::Value = map.next_value()?;
                fields.insert(key, value);
            }
        }
        let kind = kind.ok_or_else(|| {
            de::Error::custom(format!(
                "missing field `kind` ({})",
                one_of(self.kinds).trim_start_matches("one of ")
            ))
        })?;
        Ok(Tagged {
            kind,
            fields,
            kinds: self.kinds,
        })
    }
}

/// A tagged table's fields as serde's map input, each value's error prefixed with
/// its key.
struct Fields {
    iter: toml::map::IntoIter<String, toml::Value>,
    value: Option<(String, toml::Value)>,
}

impl<'de> MapAccess<'de> for Fields {
    type Error = toml::de::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Self::Error> {
        let Some((k, v)) = self.iter.next() else {
            return Ok(None);
        };
        let key = seed.deserialize(k.as_str().into_deserializer())?;
        self.value = Some((k, v));
        Ok(Some(key))
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> Result<V::Value, Self::Error> {
        let Some((k, v)) = self.value.take() else {
            return Err(de::Error::custom("a value asked for before its key"));
        };
        seed.deserialize(v)
            .map_err(|e| de::Error::custom(format!("field `{k}`: {}", e.message().trim())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        a: f64,
        #[serde(default)]
        items: Vec<Item>,
    }
    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Item {
        x: f64,
    }

    const TEXT: &str = "a = 1.0\n\n[[items]]\nx = 2.0\n\n[[items]]\nx = -3.0\n";

    #[test]
    fn validation_faults_point_at_the_field() {
        let e = parse::<Doc>("plan", TEXT, Some(Path::new("p.toml")), |d| {
            if d.a != 1.0 {
                return Err(("a".into(), "misread".into()));
            }
            match d.items.iter().position(|i| i.x < 0.0) {
                Some(k) => Err((format!("items[{k}].x"), "must not be negative".into())),
                None => Ok(()),
            }
        })
        .expect_err("x < 0");
        assert_eq!(
            e.to_string(),
            "p.toml:7:5: field `items[1].x`: must not be negative"
        );
    }

    #[test]
    fn syntax_and_unknown_keys_are_located() {
        let e = parse::<Doc>("plan", "a = 1.0\nb = 2\n", None, |_| Ok(())).expect_err("b");
        assert_eq!((e.line, e.column), (Some(2), Some(1)));
        assert!(
            e.to_string().starts_with("<plan>:2:1: unknown field `b`"),
            "{e}"
        );
        let e = parse::<Doc>("plan", "a = \n", None, |_| Ok(())).expect_err("syntax");
        assert_eq!(e.line, Some(1));
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Tagged {
        #[allow(dead_code)]
        points: Kind,
    }
    #[derive(Debug, serde::Deserialize)]
    #[serde(tag = "kind", deny_unknown_fields)]
    enum Kind {
        #[allow(dead_code)]
        One { x: f64 },
    }

    #[test]
    fn unknown_keys_of_tagged_tables_point_at_the_key() {
        let text = "[points]\nkind = \"One\"\nx = 1.0\n  speed = 3\n";
        let e = parse::<Tagged>("plan", text, None, |_| Ok(())).expect_err("speed");
        assert_eq!((e.line, e.column), (Some(4), Some(3)), "{e}");
    }

    #[test]
    fn type_errors_name_the_field() {
        let e = parse::<Doc>(
            "plan",
            "a = 1.0\n[[items]]\nx = 2\n[[items]]\nx = \"far\"\n",
            None,
            |_| Ok(()),
        )
        .expect_err("string");
        assert_eq!(
            e.to_string(),
            "<plan>:5:5: field `items[1].x`: invalid type: string \"far\", expected f64"
        );
        // The document as a whole has no field.
        let e = parse::<Doc>("plan", "items = []\n", None, |_| Ok(())).expect_err("a");
        assert_eq!(e.field, None);
        assert_eq!(e.message, "missing field `a`");
    }

    #[test]
    fn a_byte_order_mark_is_ignored_and_columns_do_not_count_it() {
        let d = parse::<Doc>("plan", "\u{feff}a = 1.5\n", None, |_| Ok(())).expect("BOM");
        assert_eq!(d.a, 1.5);
        let e = parse::<Doc>("plan", "\u{feff}a = 1.5\n", None, |_| {
            Err(("a".into(), "no".into()))
        })
        .expect_err("validate");
        assert_eq!((e.line, e.column), (Some(1), Some(5)));
        let e = parse::<Doc>("plan", "\u{feff}a = true\n", None, |_| Ok(())).expect_err("bool");
        assert_eq!(
            e.to_string(),
            "<plan>:1:5: field `a`: invalid type: boolean `true`, expected f64"
        );
    }

    #[derive(Debug, PartialEq, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Disc {
        radius: f64,
        #[serde(default)]
        sides: Option<u32>,
    }
    #[derive(Debug, PartialEq, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Rect {
        w: f64,
        h: f64,
    }
    #[derive(Debug, PartialEq)]
    enum Shape {
        Disc(Disc),
        Rect(Rect),
    }
    impl<'de> serde::Deserialize<'de> for Shape {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            let t = super::Tagged::read(d, &["disc", "rect"])?;
            match t.kind() {
                "disc" | "circle" => t.fields().map(Shape::Disc),
                "rect" => t.fields().map(Shape::Rect),
                _ => Err(t.unknown_kind()),
            }
        }
    }
    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Shapes {
        shape: Shape,
        #[serde(default)]
        more: std::collections::BTreeMap<String, Shape>,
    }

    fn shapes(text: &str) -> Result<Shapes, FileError> {
        parse::<Shapes>("shapes", text, None, |_| Ok(()))
    }

    #[test]
    fn tagged_tables_read_every_kind() {
        let s = shapes(
            "[shape]\nkind = \"rect\"\nw = 1\nh = 2.5\n[more.a]\nkind = \"circle\"\nradius = 3\n",
        )
        .expect("valid");
        assert_eq!(s.shape, Shape::Rect(Rect { w: 1.0, h: 2.5 }));
        assert_eq!(
            s.more["a"],
            Shape::Disc(Disc {
                radius: 3.0,
                sides: None
            })
        );
    }

    #[test]
    fn tagged_table_errors_name_the_field_and_what_is_accepted() {
        let cases = [
            (
                "[shape]\nkind = \"disc\"\nradius = \"big\"\n",
                "<shapes>:3:10: field `shape.radius`: invalid type: string \"big\", expected f64",
            ),
            (
                "[shape]\nkind = \"disc\"\nradius = 1\nsides = -3\n",
                "<shapes>:4:9: field `shape.sides`: invalid value: integer `-3`, expected u32",
            ),
            (
                "[shape]\nkind = \"square\"\n",
                "<shapes>:2:8: field `shape.kind`: unknown kind \"square\", expected one of \"disc\" or \"rect\"",
            ),
            (
                "[shape]\nradius = 1\n",
                "<shapes>:1:1: field `shape`: missing field `kind` (\"disc\" or \"rect\")",
            ),
            (
                "[shape]\nkind = 7\n",
                "<shapes>:2:8: field `shape.kind`: invalid type: integer `7`, expected a string",
            ),
            (
                "shape = 3\n",
                "<shapes>:1:9: field `shape`: invalid type: integer `3`, expected a table with kind = one of \"disc\" or \"rect\"",
            ),
            (
                "[shape]\nkind = \"rect\"\nw = 1\n",
                "<shapes>:1:1: field `shape`: missing field `h`",
            ),
            (
                "[shape]\nkind = \"rect\"\nw = 1\nh = 1\n  d = 1\n",
                "<shapes>:5:3: unknown field `d`, expected `w` or `h`",
            ),
            (
                "shape = { kind = \"rect\", w = 1, h = 1 }\n[more.b]\nkind = \"rect\"\nw = [1]\nh = 1\n",
                "<shapes>:4:5: field `more.b.w`: invalid type: sequence, expected f64",
            ),
        ];
        for (text, want) in cases {
            let e = shapes(text).expect_err(text);
            assert_eq!(e.to_string(), want, "{text}");
        }
    }

    #[test]
    fn field_at_finds_the_innermost_value() {
        let t = "a = 1\n[b]\nc = [1, { d = 2 }]\n";
        let at = |needle: &str| {
            let s = t.find(needle).expect("in text");
            field_at(t, &(s..s + needle.len()))
        };
        assert_eq!(at("1").as_deref(), Some("a"));
        assert_eq!(at("[1, { d = 2 }]").as_deref(), Some("b.c"));
        assert_eq!(at("{ d = 2 }").as_deref(), Some("b.c[1]"));
        assert_eq!(at("2").as_deref(), Some("b.c[1].d"));
        assert_eq!(field_at(t, &(0..1)), None);
        assert_eq!(field_at("= x", &(0..1)), None);
    }

    #[test]
    fn missing_parts_of_a_path_fall_back_to_the_deepest_found() {
        let s = span_of(TEXT, "items[1].y").expect("toml");
        assert_eq!(crate::text::line_col(TEXT, s.start).0, 6);
        assert!(span_of("= nonsense", "a").is_none());
    }
}
