//! Each sensor's detection probability `P_D` as a track engine's associator takes it, scan by
//! scan: configured (a sensor's own entry of [`Deployment::sensor_pd`], else one `P_D` for every
//! sensor: `--param pd` or the scenario's `detection.pd`), else estimated online from the
//! sensor's scans (harrier-core's [`PdEstimate`]: each scan, for every track confirmed before
//! it, detected — the scan's association updated it — or missed). Every sensor is estimated,
//! configured or not, so the API shows both; the estimates go with the tracks to another engine
//! ([`Handover::pd`](crate::Handover)), so a change of associator keeps them.

use std::collections::BTreeMap;

use harrier_core::tracker::{PdEstimate, TrackEvent};

use crate::{Deployment, EngineError, Params, SensorPdView};

/// The prior of a sensor's estimate: `P_D` 0.9 …
const PRIOR_PD: f64 = 0.9;
/// … worth this many trials (a handful of scans move it) …
const PRIOR_WEIGHT: f64 = 4.0;
/// … and the trials the estimate weighs (its forgetting, `λ = 1 − 1/MEMORY`).
const MEMORY: f64 = 200.0;
/// A configured `P_D` of 1 is taken as this (the associators need `P_D < 1`).
const PD_CEILING: f64 = 0.999;

/// The `P_D` of every sensor of one engine.
#[derive(Debug, Clone)]
pub struct SensorPds {
    /// A sensor's own configured `P_D`, by `vehicle/sensor` or sensor id.
    configured: BTreeMap<String, f64>,
    /// Every other sensor's, when given.
    all: Option<f64>,
    /// The estimates, by `vehicle/sensor`.
    estimates: BTreeMap<String, PdEstimate>,
    /// A new sensor's estimate.
    prior: PdEstimate,
}

/// `vehicle/sensor`, the key of a sensor's estimate.
pub fn key(vehicle: &str, sensor: &str) -> String {
    format!("{vehicle}/{sensor}")
}

impl SensorPds {
    /// The configuration of deployment `d` with the parameters `p` (`pd`), no estimate yet.
    /// Fails for a configured `P_D` outside (0, 1].
    pub fn new(d: &Deployment, p: &Params) -> Result<Self, EngineError> {
        let all = p.opt("pd").or_else(|| d.detection.as_ref().map(|x| x.pd));
        for (name, pd) in all
            .iter()
            .map(|pd| ("pd", pd))
            .chain(d.sensor_pd.iter().map(|(k, v)| (k.as_str(), v)))
        {
            if !(*pd > 0.0 && *pd <= 1.0) {
                return Err(crate::setup(format!(
                    "the detection probability of {name} must be in (0, 1], got {pd}"
                )));
            }
        }
        Ok(Self {
            configured: d.sensor_pd.clone(),
            all,
            estimates: BTreeMap::new(),
            prior: PdEstimate::new(PRIOR_PD, PRIOR_WEIGHT, MEMORY)?,
        })
    }

    /// The configured `P_D` of `vehicle/sensor`, if any.
    fn configured(&self, vehicle: &str, sensor: &str) -> Option<f64> {
        self.configured
            .get(&key(vehicle, sensor))
            .or_else(|| self.configured.get(sensor))
            .copied()
            .or(self.all)
            .map(|pd| pd.min(PD_CEILING))
    }

    /// The `P_D` of the next scan of `vehicle/sensor`: configured, else its estimate (the prior
    /// before its first scan).
    pub fn pd(&self, vehicle: &str, sensor: &str) -> f64 {
        self.configured(vehicle, sensor).unwrap_or_else(|| {
            self.estimates
                .get(&key(vehicle, sensor))
                .map_or(PRIOR_PD, PdEstimate::pd)
        })
    }

    /// Counts a scan of `vehicle/sensor` that was processed in time order: each track of
    /// `confirmed` (those confirmed before the scan) detected when `events` updated it, else
    /// missed.
    pub fn observe(
        &mut self,
        vehicle: &str,
        sensor: &str,
        confirmed: &[u64],
        events: &[TrackEvent],
    ) {
        let detected = confirmed
            .iter()
            .filter(|id| {
                events
                    .iter()
                    .any(|e| matches!(e, TrackEvent::Updated { id: u, .. } if u == *id))
            })
            .count();
        let e = self
            .estimates
            .entry(key(vehicle, sensor))
            .or_insert(self.prior);
        let detected = u32::try_from(detected).unwrap_or(u32::MAX);
        let all = u32::try_from(confirmed.len()).unwrap_or(u32::MAX);
        e.observe(detected, all - detected);
    }

    /// Every sensor seen so far, by `vehicle/sensor`.
    pub fn views(&self) -> Vec<SensorPdView> {
        self.estimates
            .iter()
            .map(|(k, e)| {
                let (vehicle, sensor) = k.split_once('/').unwrap_or(("", k));
                let configured = self.configured(vehicle, sensor);
                SensorPdView {
                    vehicle: vehicle.into(),
                    sensor: sensor.into(),
                    pd: configured.unwrap_or_else(|| e.pd()),
                    configured: configured.is_some(),
                    estimate: e.mean(),
                    estimate_std: e.std(),
                    trials: e.trials(),
                }
            })
            .collect()
    }

    /// The estimates, for another engine ([`Handover::pd`](crate::Handover)).
    pub fn estimates(&self) -> &BTreeMap<String, PdEstimate> {
        &self.estimates
    }

    /// Continues `estimates` (another engine's).
    pub fn adopt(&mut self, estimates: &BTreeMap<String, PdEstimate>) {
        self.estimates.clone_from(estimates);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn events(updated: &[u64], coasted: &[u64]) -> Vec<TrackEvent> {
        updated
            .iter()
            .map(|&id| TrackEvent::Updated {
                id,
                detection: 0,
                nis: 1.0,
            })
            .chain(
                coasted
                    .iter()
                    .map(|&id| TrackEvent::Coasted { id, misses: 1 }),
            )
            .collect()
    }

    #[test]
    fn a_sensor_is_configured_by_its_key_its_id_or_every_sensor_else_estimated() {
        let mut d = Deployment::planar(2);
        d.sensor_pd.insert("2/cam".into(), 0.6);
        d.sensor_pd.insert("cam".into(), 0.5);
        let mut pds = SensorPds::new(&d, &Params::default()).expect("valid");
        assert_eq!(pds.pd("2", "cam"), 0.6);
        assert_eq!(pds.pd("1", "cam"), 0.5);
        // Not configured: the prior, then the estimate.
        assert_eq!(pds.pd("1", "radar"), PRIOR_PD);
        for _ in 0..400 {
            pds.observe("1", "radar", &[1, 2], &events(&[1], &[2]));
        }
        assert!(
            (pds.pd("1", "radar") - 0.5).abs() < 0.01,
            "{}",
            pds.pd("1", "radar")
        );
        let views = pds.views();
        assert_eq!(views.len(), 1);
        assert_eq!(
            (views[0].vehicle.as_str(), views[0].sensor.as_str()),
            ("1", "radar")
        );
        assert!(!views[0].configured && views[0].trials == 800);
        // `--param pd` configures every sensor without an entry of its own.
        let p = Params::parse(&["pd=1"]).expect("parameters");
        let pds = SensorPds::new(&d, &p).expect("valid");
        assert_eq!(
            (pds.pd("1", "radar"), pds.pd("1", "cam")),
            (PD_CEILING, 0.5)
        );
        // Out of range.
        d.sensor_pd.insert("bad".into(), 1.5);
        let e = SensorPds::new(&d, &Params::default()).unwrap_err();
        assert!(e.to_string().contains("bad"), "{e}");
    }
}
