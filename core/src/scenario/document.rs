//! `scenario.json` as a generator writes it: [`ScenarioDocument`], with the `frame` and
//! `generator` blocks readers do not interpret.

use serde::{Deserialize, Serialize};

use super::types::Scenario;

/// `frame` block: ENU metres about an optional geodetic origin (FORMAT.md §2).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Frame {
    /// Always `ENU`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Always `m`.
    pub units: String,
    /// WGS-84 origin of the frame, when it has one.
    pub origin_geodetic: Option<crate::detection::GeoPoint>,
}

impl Frame {
    /// The ENU frame (metres) at `origin`.
    pub fn enu(origin: Option<crate::detection::GeoPoint>) -> Self {
        Self {
            kind: "ENU".into(),
            units: "m".into(),
            origin_geodetic: origin,
        }
    }
}

/// `generator` block: provenance of a generated scenario. Estimators never read it.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Generator {
    /// Which generator wrote the scenario.
    pub family: String,
    /// Its seed.
    pub seed: u64,
    /// Everything else needed to regenerate it.
    pub params: serde_json::Value,
}

/// `scenario.json` as a generator writes it: the [`Scenario`] readers parse, plus the blocks they
/// do not interpret — the `frame`, the keys of format extensions (FORMAT-MULTI.md's `targets` and
/// `detection`) and the `generator`. [`Scenario::parse`] reads the result back.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioDocument {
    /// What readers parse.
    #[serde(flatten)]
    pub scenario: Scenario,
    /// The local frame.
    pub frame: Frame,
    /// Extension keys, written at the top level (must not repeat a [`Scenario`] key).
    #[serde(flatten)]
    pub extensions: serde_json::Map<String, serde_json::Value>,
    /// Provenance.
    pub generator: Generator,
}

impl ScenarioDocument {
    /// Pretty JSON text of `scenario.json`, ending with a newline.
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        Ok(text)
    }
}
