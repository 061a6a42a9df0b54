//! `--config FILE`: a plant configuration ([`PlantConfig`]) in TOML or JSON.
//!
//! The format is the file's extension (`.toml`, `.json`) or, for any other
//! name, its content: JSON when the first non-space character is `{`, TOML
//! otherwise. An error names the file, the line and column, and the field
//! when it can be found (see [`blame`]). The file is also read as a generic
//! table, so the run can say which of its fields a flag overrides.

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use anyhow::{Context, Result, anyhow};
use kflex_model::PlantConfig;
use serde_json::{Map, Value};

/// How a configuration file is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// TOML.
    Toml,
    /// JSON.
    Json,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Toml => "TOML",
            Self::Json => "JSON",
        })
    }
}

impl Format {
    /// By extension (`.toml`, `.json`, any case); otherwise by content.
    pub fn of(path: &Path, text: &str) -> Self {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("toml") => Self::Toml,
            Some("json") => Self::Json,
            _ if text.trim_start().starts_with('{') => Self::Json,
            _ => Self::Toml,
        }
    }
}

/// A configuration file as read.
#[derive(Debug)]
pub struct ConfigFile {
    /// The configuration: the file's fields, defaults for the others.
    pub config: PlantConfig,
    /// The top-level fields the file sets, each with its value as written
    /// there (in the file's syntax).
    pub fields: BTreeMap<String, String>,
}

/// Reads and parses `path`.
///
/// # Errors
/// The file cannot be read, or is not a valid configuration in its format:
/// the message names the file, the line and column where the parser says,
/// and the field where one is to blame.
pub fn load(path: &Path) -> Result<ConfigFile> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let format = Format::of(path, text);
    let located = |line: Option<(usize, usize)>, field: Option<String>, message: &str| {
        let mut at = format!("{} ({format})", path.display());
        if let Some((line, column)) = line {
            at.push_str(&format!(", line {line}, column {column}"));
        }
        if let Some(field) = field {
            at.push_str(&format!(", field `{field}`"));
        }
        anyhow!("{at}: {message}")
    };
    match format {
        Format::Json => {
            let json_error = |e: &serde_json::Error| {
                let message = e.to_string();
                let suffix = format!(" at line {} column {}", e.line(), e.column());
                let message = message.strip_suffix(&suffix).unwrap_or(&message).to_owned();
                ((e.line() > 0).then_some((e.line(), e.column())), message)
            };
            let doc: Value = serde_json::from_str(text).map_err(|e| {
                let (line, message) = json_error(&e);
                located(line, None, &message)
            })?;
            let config = serde_json::from_str::<PlantConfig>(text).map_err(|e| {
                let (line, message) = json_error(&e);
                located(line, blame(&doc), &message)
            })?;
            let fields = doc
                .as_object()
                .map(|o| o.iter().map(|(k, v)| (k.clone(), v.to_string())).collect())
                .unwrap_or_default();
            Ok(ConfigFile { config, fields })
        }
        Format::Toml => {
            let line_of = |e: &toml::de::Error| e.span().map(|s| line_column(text, s.start));
            let table: toml::Table = toml::from_str(text)
                .map_err(|e| located(line_of(&e), None, e.message().trim_end()))?;
            let config = toml::from_str::<PlantConfig>(text).map_err(|e| {
                let field = serde_json::to_value(&table)
                    .ok()
                    .and_then(|doc| blame(&doc));
                located(line_of(&e), field, e.message().trim_end())
            })?;
            let fields = table
                .iter()
                .map(|(k, v)| (k.clone(), v.to_string()))
                .collect();
            Ok(ConfigFile { config, fields })
        }
    }
}

/// 1-based line and column (in characters) of byte `offset` of `text`.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut end = offset.min(text.len());
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let before = &text[..end];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The dotted path of the field to blame for `doc` not being a [`PlantConfig`],
/// found by trying parts of the document alone: descend into the field that
/// alone fails the same way, unless the table it sits in fails even when empty
/// (then the table is to blame: a required field is missing). `None` when `doc`
/// is fine or no single field reproduces the failure.
fn blame(doc: &Value) -> Option<String> {
    let failure = |v: &Value| {
        serde_json::from_value::<PlantConfig>(v.clone())
            .err()
            .map(|e| e.to_string())
    };
    let whole = failure(doc)?;
    // `leaf` at `path` inside otherwise empty tables
    let nest = |path: &[&str], leaf: Value| {
        path.iter().rev().fold(leaf, |inner, key| {
            Value::Object(Map::from_iter([((*key).to_owned(), inner)]))
        })
    };
    let mut path: Vec<&str> = Vec::new();
    let mut node = doc;
    while let Some(table) = node.as_object() {
        if !path.is_empty() && failure(&nest(&path, Value::Object(Map::new()))).is_some() {
            break;
        }
        let culprit = table.iter().find(|(key, value)| {
            let mut at = path.clone();
            at.push(key.as_str());
            failure(&nest(&at, (*value).clone())).as_ref() == Some(&whole)
        });
        let Some((key, value)) = culprit else { break };
        path.push(key);
        node = value;
    }
    (!path.is_empty()).then(|| path.join("."))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn format_by_extension_then_by_content() {
        assert_eq!(Format::of(Path::new("a.toml"), "{"), Format::Toml);
        assert_eq!(Format::of(Path::new("a.JSON"), "x = 1"), Format::Json);
        assert_eq!(
            Format::of(Path::new("a.conf"), "  \n{\"seed\": 1}"),
            Format::Json
        );
        assert_eq!(Format::of(Path::new("plant"), "seed = 1"), Format::Toml);
    }

    #[test]
    fn line_and_column_count_characters() {
        let text = "a = 1\nbé = x\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 6), (2, 1));
        assert_eq!(line_column(text, text.find('x').unwrap()), (2, 6));
        // inside a character, or past the end: no panic
        assert_eq!(line_column(text, text.find('é').unwrap() + 1), (2, 2));
        assert_eq!(line_column(text, 99), (3, 1));
    }

    #[test]
    fn blame_names_the_field_at_fault() {
        let doc: Value = serde_json::from_str(
            r#"{"seed": 3, "joint": {"contact_stiffness_nmm_per_rad": "stiff"}}"#,
        )
        .unwrap();
        assert_eq!(
            blame(&doc).as_deref(),
            Some("joint.contact_stiffness_nmm_per_rad")
        );
        let doc: Value = serde_json::from_str(r#"{"geometry": {"n_segmentz": 2}}"#).unwrap();
        assert_eq!(blame(&doc).as_deref(), Some("geometry.n_segmentz"));
        let doc: Value = serde_json::from_str(r#"{"seed": -1}"#).unwrap();
        assert_eq!(blame(&doc).as_deref(), Some("seed"));
        let doc: Value = serde_json::from_str(r#"{"seed": 1}"#).unwrap();
        assert_eq!(blame(&doc), None);
    }
}
