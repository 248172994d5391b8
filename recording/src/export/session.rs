//! What an export reads of a session ([`Recorded`]: its summary, configuration, scans and
//! truth), and its scans in the session's frame ([`framed`]: a measurement line per detection,
//! each sensor's kind, noise and scan times).

use std::collections::{BTreeMap, BTreeSet};

use harrier_core::detection::{DetectionScan, GeoPoint, TruthSample};
use harrier_core::measurement::Geometry;
use harrier_core::scenario as fmt;
use harrier_link::detections::scan_in_frame;
use harrier_link::geo::LocalFrame;
use harrier_link::scenario_out;

use super::times::{Line, SensorEntry, TimeLine};
use crate::reader::{Db, SessionError, SessionInfo};

/// The scans of session `id` in `frame`, one measurement line per detection (time on `line`,
/// no sensor id yet), and each (vehicle, sensor)'s kind, noise and scan times.
pub(super) fn framed(
    d: &Db<'_>,
    id: i64,
    scans: &[(i64, DetectionScan)],
    line: TimeLine,
    frame: &LocalFrame,
    geometry: Geometry,
) -> Result<Framed, SessionError> {
    let mut sensors: BTreeMap<(u8, String), SensorEntry> = BTreeMap::new();
    let mut lines = Vec::new();
    let mut several = false;
    let mut times = Vec::with_capacity(scans.len());
    for (row, scan) in scans {
        let t = micros(line.relative(scan.t, scan.time_unix).unwrap_or(scan.t));
        times.push(t);
        let local = scan_in_frame(scan, frame, geometry)
            .map_err(|e| d.malformed(id, format!("scans row {row}: {e}")))?;
        let key = (scan.vehicle, scan.sensor.clone());
        let entry = sensors.entry(key.clone()).or_insert_with(|| SensorEntry {
            kind: scan.kind,
            noise_std: scan.noise_std.clone(),
            times: Vec::new(),
        });
        if entry.kind != scan.kind || entry.noise_std.len() != scan.noise_std.len() {
            return Err(d.export_error(
                id,
                format!(
                    "sensor {} of vehicle {} changes from {:?} ({} components) to {:?} ({}) \
                     at seq {}",
                    scan.sensor,
                    scan.vehicle,
                    entry.kind,
                    entry.noise_std.len(),
                    scan.kind,
                    scan.noise_std.len(),
                    scan.seq
                ),
            ));
        }
        entry.times.push(t);
        several |= local.detections.len() > 1;
        for z in local.detections.iter() {
            lines.push(Line {
                t,
                sensor: key.clone(),
                m: scenario_out::measurement(&local, t, "", z.clone()),
            });
        }
    }
    Ok(Framed {
        sensors,
        lines,
        times,
        several,
    })
}

/// A session's scans in its frame ([`framed`]).
#[derive(Debug)]
pub(super) struct Framed {
    /// Each (vehicle, sensor).
    pub(super) sensors: BTreeMap<(u8, String), SensorEntry>,
    /// A line per detection, in scan order.
    pub(super) lines: Vec<Line>,
    /// Each scan's relative time, in scan order.
    pub(super) times: Vec<f64>,
    /// Whether a scan holds several detections.
    pub(super) several: bool,
}

/// Rounds a relative time to the microsecond (the formats' tolerance).
pub(super) fn micros(t: f64) -> f64 {
    (t * 1e6).round() / 1e6
}

/// The settings of the session's configuration an export uses: motion models, roads, scan
/// period (defaults of `harrier serve` when a key is missing).
fn deployment(config_json: &str) -> Result<(fmt::Motion, Vec<fmt::Road>, f64), String> {
    let v: serde_json::Value =
        serde_json::from_str(config_json).map_err(|e| format!("config_json: {e}"))?;
    let tracker = &v["tracker"];
    let motion = match &tracker["motion"] {
        serde_json::Value::Null => fmt::Motion::cv(1.0),
        m => serde_json::from_value(m.clone())
            .map_err(|e| format!("config_json tracker.motion: {e}"))?,
    };
    let roads = match &tracker["roads"] {
        serde_json::Value::Null => Vec::new(),
        r => serde_json::from_value(r.clone())
            .map_err(|e| format!("config_json tracker.roads: {e}"))?,
    };
    let dt = tracker["scan_period_s"]
        .as_f64()
        .filter(|d| d.is_finite() && *d > 0.0)
        .unwrap_or(1.0);
    Ok((motion, roads, dt))
}

/// What an export reads of a session: its summary, the settings of its configuration an export
/// uses, and its scans and truth samples with their row ids.
pub(super) struct Recorded {
    pub(super) info: SessionInfo,
    pub(super) motion: fmt::Motion,
    pub(super) roads: Vec<fmt::Road>,
    /// The configured scan period (s): a single-target export's time step, and a multi-target
    /// one's when no sensor scanned twice.
    pub(super) scan_period: f64,
    pub(super) scans: Vec<(i64, DetectionScan)>,
    pub(super) truth: Vec<(i64, TruthSample)>,
}

impl Recorded {
    /// Reads session `id` of `d`; one without scans is refused.
    pub(super) fn read(d: &Db<'_>, id: i64) -> Result<Self, SessionError> {
        let info = d.info(id)?;
        let (motion, roads, scan_period) = deployment(&d.config_json(id)?)
            .map_err(|m| d.malformed(id, format!("sessions row: {m}")))?;
        let scans = d.rows("scans", id, DetectionScan::from_json)?;
        let truth = d.rows("truth", id, TruthSample::from_json)?;
        if scans.is_empty() {
            return Err(d.export_error(id, "it has no scans"));
        }
        Ok(Self {
            info,
            motion,
            roads,
            scan_period,
            scans,
            truth,
        })
    }

    /// The WGS-84 origin of the session's ENU frame.
    pub(super) fn origin(&self) -> GeoPoint {
        let i = &self.info;
        GeoPoint::new(i.origin_lat_deg, i.origin_lon_deg, i.origin_alt_m)
    }

    /// Whether the truth has several targets.
    pub(super) fn several_targets(&self) -> bool {
        let ids: BTreeSet<&str> = self
            .truth
            .iter()
            .flat_map(|s| s.1.targets.iter().map(|g| g.id.as_str()))
            .collect();
        ids.len() > 1
    }
}
