//! `[registration]`: live sensor registration, the sensors whose biases the tracker estimates
//! jointly with its tracks (harrier-engine's registrar, harrier-core's `BiasBank`). Off unless a
//! sensor is listed.

use harrier_core::measurement::MeasKind;
use harrier_core::registration::SensorBias;
use harrier_engine::RegisteredSensor;
use serde::{Deserialize, Serialize};

use super::error::ConfigError;

/// Live sensor registration (`[registration]`).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RegistrationConfig {
    /// The registered sensors (`[[registration.sensors]]`); empty: registration is off.
    pub sensors: Vec<RegistrationSensor>,
}

/// One registered sensor: which scans are its and its bias terms.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RegistrationSensor {
    /// Vehicle label of its scans (MAVLink system id).
    pub vehicle: String,
    /// Sensor id of its scans on the vehicle.
    pub sensor: String,
    /// Measurement kind of its scans: `range_bearing` or `az_el`.
    pub kind: MeasKind,
    /// Its bias terms and priors, FORMAT-REGISTRATION.md §1's `bias` block (`offset`, `scale`,
    /// `time_offset`); unset: the kind's typical terms (`SensorBias::typical`).
    #[serde(default)]
    pub bias: Option<serde_json::Value>,
}

impl RegistrationSensor {
    /// The engine's form, or why not.
    fn registered(&self) -> Result<RegisteredSensor, String> {
        let name = format!("registration.sensors {}/{}", self.vehicle, self.sensor);
        if !matches!(self.kind, MeasKind::RangeBearing | MeasKind::AzEl) {
            return Err(format!(
                "{name}: kind {} is not registered (range_bearing, az_el)",
                self.kind.as_str()
            ));
        }
        let bias = match &self.bias {
            None => SensorBias::typical(self.kind),
            Some(block) => SensorBias::from_block(block, self.kind.len(None))
                .map_err(|e| format!("{name}: {e}"))?
                .ok_or_else(|| {
                    format!("{name}: the bias block has no offset, scale or time_offset")
                })?,
        };
        Ok(RegisteredSensor {
            vehicle: self.vehicle.clone(),
            sensor: self.sensor.clone(),
            kind: self.kind,
            bias,
        })
    }
}

impl RegistrationConfig {
    /// Checks every sensor's kind and bias block, and that no sensor is listed twice.
    pub fn check(&self) -> Result<(), ConfigError> {
        self.registered().map(|_| ())
    }

    /// The registered sensors in the engine's form.
    pub fn registered(&self) -> Result<Vec<RegisteredSensor>, ConfigError> {
        let mut out: Vec<RegisteredSensor> = Vec::with_capacity(self.sensors.len());
        for s in &self.sensors {
            let r = s.registered().map_err(ConfigError::Invalid)?;
            if out
                .iter()
                .any(|o| o.vehicle == r.vehicle && o.sensor == r.sensor)
            {
                return Err(ConfigError::Invalid(format!(
                    "registration.sensors: {}/{} is listed twice",
                    r.vehicle, r.sensor
                )));
            }
            out.push(r);
        }
        Ok(out)
    }
}
