//! What can be wrong with a scenario ([`ScenarioError`], naming its [`Source`]) and the checks
//! of single numbers serde runs while reading one (with the line and column serde_json reports).

use std::fmt;

use serde::de::Error as _;
use serde::{Deserialize, Deserializer};

/// Names of the built-in scenarios, for `--scenario NAME`.
pub const PRESETS: [&str; 6] = [
    "cimm-road",
    "leader",
    "radar",
    "radar-abrupt",
    "radar-markov",
    "crossing",
];

fn checked<'de, D: Deserializer<'de>>(
    d: D,
    ok: impl Fn(f64) -> bool,
    what: &str,
) -> Result<f64, D::Error> {
    let v = f64::deserialize(d)?;
    if v.is_finite() && ok(v) {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "invalid value {v}: must be {what}"
        )))
    }
}
pub(super) fn positive<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, |v| v > 0.0, "> 0")
}
pub(super) fn non_negative<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, |v| v >= 0.0, ">= 0")
}
pub(super) fn probability<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    checked(d, |v| (0.0..=1.0).contains(&v), "a probability in [0, 1]")
}

/// Where a scenario came from, for error messages.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Source {
    /// A built-in preset.
    Preset(String),
    /// A file.
    File(String),
    /// A scenario already in memory, by name.
    Named(String),
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Preset(n) => write!(f, "preset {n}"),
            Self::File(p) => f.write_str(p),
            Self::Named(n) => write!(f, "scenario {n}"),
        }
    }
}

/// A scenario that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ScenarioError {
    /// Neither a preset nor a readable file.
    #[error("cannot read scenario {name:?}: {message} (presets: {presets})", presets = PRESETS.join(", "))]
    NotFound {
        /// What was asked for.
        name: String,
        /// The I/O error.
        message: String,
    },
    /// Malformed JSON, unknown or missing key, or an out-of-range number.
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// Inconsistent values.
    #[error("{origin}: {message}")]
    Invalid {
        /// The file or preset.
        origin: String,
        /// What is wrong, naming the field.
        message: String,
    },
}
