//! Strict TOML input files (instrument configs, plans, simulator configs): parse,
//! validate whole, and report the first fault as `FILE:LINE:COL: field `NAME`: why`.
//!
//! Validation functions name a fault by its dotted field path (`motion.axes[1].max`);
//! [`span_of`] turns that path back into the place in the text, so that every input
//! error points at the line to fix.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
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

    /// A fault at `field` of `text`, located by [`span_of`].
    pub fn at_field(
        kind: &'static str,
        path: Option<&Path>,
        text: &str,
        field: String,
        message: impl Into<String>,
    ) -> Self {
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
/// labels errors.
pub fn parse<T: DeserializeOwned>(
    kind: &'static str,
    text: &str,
    path: Option<&Path>,
    validate: impl FnOnce(&T) -> Result<(), (String, String)>,
) -> Result<T, FileError> {
    let value: T = toml::from_str(text).map_err(|e| {
        let message = e.message().trim();
        let mut err = FileError::whole(kind, path, message);
        if let Some(s) = e.span() {
            let s = refine(text, s, message);
            let (l, c) = crate::text::line_col(text, s.start);
            err.line = Some(l);
            err.column = Some(c);
        }
        err
    })?;
    validate(&value)
        .map_err(|(field, message)| FileError::at_field(kind, path, text, field, message))?;
    Ok(value)
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
    fn missing_parts_of_a_path_fall_back_to_the_deepest_found() {
        let s = span_of(TEXT, "items[1].y").expect("toml");
        assert_eq!(crate::text::line_col(TEXT, s.start).0, 6);
        assert!(span_of("= nonsense", "a").is_none());
    }
}
