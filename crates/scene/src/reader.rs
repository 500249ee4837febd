//! A typed reader over TOML's spanned document tree.
//!
//! Every accessor records the key path (`object[2].base.radius`) and the
//! source span, so each error names the file, line, column and key.
//! Tables declare their valid keys up front; any other key is an error that
//! lists the valid ones.

use std::ops::Range;
use std::path::Path;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// A scene-file error: `file:line:column: key: message`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}:{column}: {}{message}", if key.is_empty() { String::new() } else { format!("{key}: ") })]
pub struct SceneError {
    /// File as given.
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column (characters).
    pub column: usize,
    /// Key path, empty for syntax errors.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

/// The document being read.
pub struct Doc<'s> {
    file: String,
    src: &'s str,
}

impl<'s> Doc<'s> {
    /// Wraps a source text; `file` is used in messages.
    pub fn new(file: &Path, src: &'s str) -> Self {
        Self {
            file: file.display().to_string(),
            src,
        }
    }

    /// Line and column of a byte offset.
    pub fn position(&self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.src.len());
        let before = &self.src[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map(|i| i + 1).unwrap_or(0);
        let column = self.src[line_start..offset].chars().count() + 1;
        (line, column)
    }

    /// An error at `span`.
    pub fn error(&self, span: Range<usize>, key: &str, message: impl Into<String>) -> SceneError {
        let (line, column) = self.position(span.start);
        SceneError {
            file: self.file.clone(),
            line,
            column,
            key: key.to_string(),
            message: message.into(),
        }
    }

    /// Parses the document into its root table.
    pub fn parse(&self) -> Result<Spanned<DeTable<'s>>> {
        DeTable::parse(self.src).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            let mut msg = e.message().trim().to_string();
            // The parser names no key; the span starts at it (`width = 4`,
            // or a table header `[film]`).
            if msg == "duplicate key" {
                let rest = self.src.get(span.start..).unwrap_or("");
                let key = rest
                    .split(['=', '\n'])
                    .next()
                    .unwrap_or("")
                    .trim()
                    .trim_matches(['[', ']']);
                if !key.is_empty() {
                    msg = format!("duplicate key `{key}`");
                }
            }
            self.error(span, "", format!("TOML syntax error: {msg}"))
        })
    }
}

/// Result alias.
pub type Result<T> = std::result::Result<T, SceneError>;

/// A table being read.
pub struct Table<'d, 'a, 's> {
    pub(crate) doc: &'d Doc<'s>,
    table: &'a DeTable<'s>,
    span: Range<usize>,
    path: String,
}

/// A value being read.
#[derive(Clone)]
pub struct Value<'d, 'a, 's> {
    pub(crate) doc: &'d Doc<'s>,
    v: &'a Spanned<DeValue<'s>>,
    pub(crate) path: String,
}

fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

fn kind(v: &DeValue) -> &'static str {
    match v {
        DeValue::String(_) => "a string",
        DeValue::Integer(_) => "an integer",
        DeValue::Float(_) => "a float",
        DeValue::Boolean(_) => "a boolean",
        DeValue::Datetime(_) => "a date",
        DeValue::Array(_) => "an array",
        DeValue::Table(_) => "a table",
    }
}

impl<'d, 'a, 's> Table<'d, 'a, 's> {
    /// The root table of a document.
    pub fn root(doc: &'d Doc<'s>, t: &'a Spanned<DeTable<'s>>) -> Self {
        Self {
            doc,
            table: t.get_ref(),
            span: t.span(),
            path: String::new(),
        }
    }

    /// An error located at the table.
    pub fn error(&self, message: impl Into<String>) -> SceneError {
        self.doc.error(self.span.clone(), &self.path, message)
    }

    /// Rejects any key not in `valid`.
    pub fn allow(&self, valid: &[&str]) -> Result<()> {
        for (k, _) in self.table.iter() {
            if !valid.contains(&k.get_ref().as_ref()) {
                let mut list: Vec<&str> = valid.to_vec();
                list.sort_unstable();
                return Err(self.doc.error(
                    k.span(),
                    &join(&self.path, k.get_ref()),
                    format!("unknown key (valid keys here: {})", list.join(", ")),
                ));
            }
        }
        Ok(())
    }

    /// The value of `key`, if present.
    pub fn get(&self, key: &str) -> Option<Value<'d, 'a, 's>> {
        self.table
            .iter()
            .find(|(k, _)| k.get_ref().as_ref() == key)
            .map(|(_, v)| Value {
                doc: self.doc,
                v,
                path: join(&self.path, key),
            })
    }

    /// The value of `key`, or a "missing" error.
    pub fn req(&self, key: &str) -> Result<Value<'d, 'a, 's>> {
        self.get(key).ok_or_else(|| {
            self.doc.error(
                self.span.clone(),
                &join(&self.path, key),
                "missing required key",
            )
        })
    }
}

impl<'d, 'a, 's> Value<'d, 'a, 's> {
    /// An error located at this value.
    pub fn error(&self, message: impl Into<String>) -> SceneError {
        self.doc.error(self.v.span(), &self.path, message)
    }

    fn expected(&self, what: &str) -> SceneError {
        self.error(format!("expected {what}, found {}", kind(self.v.get_ref())))
    }

    /// A finite number (integer or float).
    pub fn f64(&self) -> Result<f64> {
        let x = match self.v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .map(|x| x as f64)
                .map_err(|_| self.error("integer out of range"))?,
            DeValue::Float(f) => {
                let s = f.as_str().replace('_', "");
                s.parse::<f64>()
                    .map_err(|_| self.error(format!("invalid number `{s}`")))?
            }
            _ => return Err(self.expected("a number")),
        };
        if !x.is_finite() {
            return Err(self.error(format!("must be a finite number, got {x}")));
        }
        Ok(x)
    }

    /// A number `> 0`.
    pub fn positive(&self) -> Result<f64> {
        let x = self.f64()?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.error(format!("must be positive, got {x}")))
        }
    }

    /// A non-negative integer no larger than `max`.
    pub fn uint(&self, min: u64, max: u64) -> Result<u64> {
        let DeValue::Integer(i) = self.v.get_ref() else {
            return Err(self.expected("an integer"));
        };
        let x = i64::from_str_radix(i.as_str(), i.radix())
            .map_err(|_| self.error("integer out of range"))?;
        if x < min as i64 || (x as u64) > max {
            return Err(self.error(format!("must lie in {min}..={max}, got {x}")));
        }
        Ok(x as u64)
    }

    /// A boolean.
    pub fn bool(&self) -> Result<bool> {
        match self.v.get_ref() {
            DeValue::Boolean(b) => Ok(*b),
            _ => Err(self.expected("a boolean (true or false)")),
        }
    }

    /// A string.
    pub fn str(&self) -> Result<&'a str> {
        match self.v.get_ref() {
            DeValue::String(s) => Ok(s.as_ref()),
            _ => Err(self.expected("a string")),
        }
    }

    /// One of `choices`.
    pub fn choice(&self, choices: &[&str]) -> Result<&'a str> {
        let s = self.str()?;
        if choices.contains(&s) {
            Ok(s)
        } else {
            Err(self.error(format!(
                "unknown value \"{s}\" (valid: {})",
                choices.join(", ")
            )))
        }
    }

    /// The elements of an array.
    pub fn array(&self) -> Result<Vec<Value<'d, 'a, 's>>> {
        match self.v.get_ref() {
            DeValue::Array(a) => Ok(a
                .iter()
                .enumerate()
                .map(|(i, v)| Value {
                    doc: self.doc,
                    v,
                    path: format!("{}[{i}]", self.path),
                })
                .collect()),
            _ => Err(self.expected("an array")),
        }
    }

    /// `N` finite numbers.
    pub fn numbers<const N: usize>(&self) -> Result<[f64; N]> {
        let a = self.array()?;
        if a.len() != N {
            return Err(self.error(format!(
                "expected an array of {N} numbers, found {}",
                a.len()
            )));
        }
        let mut out = [0.0; N];
        for (o, v) in out.iter_mut().zip(&a) {
            *o = v.f64()?;
        }
        Ok(out)
    }

    /// A table.
    pub fn table(&self) -> Result<Table<'d, 'a, 's>> {
        match self.v.get_ref() {
            DeValue::Table(t) => Ok(Table {
                doc: self.doc,
                table: t,
                span: self.v.span(),
                path: self.path.clone(),
            }),
            _ => Err(self.expected("a table")),
        }
    }

    /// An array of tables (`[[name]]`).
    pub fn tables(&self) -> Result<Vec<Table<'d, 'a, 's>>> {
        self.array()?.iter().map(|v| v.table()).collect()
    }
}
