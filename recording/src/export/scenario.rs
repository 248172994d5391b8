//! The scenario's files built from the framed session: `measurements.jsonl`, the platforms
//! and sensors, a single-target export's prior, and `scenario.json`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use harrier_core::measurement::{
    Geometry, Locate, MeasKind, MeasurementModel, PositionFix, SensorModel, WithSensor,
};
use harrier_core::scenario as fmt;
use harrier_link::scenario_out;
use nalgebra::{SVector, Vector3};
use serde_json::json;

use super::session::Recorded;
use super::times::{Line, SensorEntry};
use super::times::{ScanTimes, TimeLine};
use super::truth::TargetTruth;

/// Velocity standard deviation of an export's prior (m/s): a ground target of unknown speed.
const PRIOR_VEL_STD_MPS: f64 = 15.0;
/// An export's prior inflates the first detection's position-fix covariance by this factor (the
/// estimator updates with that detection again).
const PRIOR_POS_INFLATION: f64 = 4.0;

/// Calls `locate` on the concrete model of a run-time sensor.
struct LocateWith<'a>(&'a [f64]);

impl WithSensor<4> for LocateWith<'_> {
    type Output = Option<PositionFix>;
    fn with<H, const M: usize>(self, model: &H) -> Option<PositionFix>
    where
        H: MeasurementModel<4, M> + Locate<M>,
    {
        (self.0.len() == M)
            .then(|| model.locate(&SVector::<f64, M>::from_column_slice(self.0)))
            .flatten()
    }
}

/// The prior of a single-target export: the first detection of `lines` (sorted) that fixes a
/// position, at its time, its position covariance inflated, velocity 0 ± [`PRIOR_VEL_STD_MPS`].
pub(super) fn first_fix_prior(
    lines: &[Line],
    sensors: &BTreeMap<(u8, String), SensorEntry>,
    geometry: Geometry,
) -> Option<fmt::Prior> {
    lines.iter().find_map(|l| {
        let e = sensors.get(&l.sensor)?;
        let pos = Vector3::from(l.m.platform.pos);
        let model = SensorModel::new(e.kind, geometry, pos, &e.noise_std, None).ok()?;
        let fix = model.apply(LocateWith(&l.m.z))?;
        let (pv, vv) = (PRIOR_POS_INFLATION, PRIOR_VEL_STD_MPS * PRIOR_VEL_STD_MPS);
        let c = fix.cov;
        Some(fmt::Prior {
            t: l.m.t,
            state: [fix.pos.x, fix.pos.y, geometry.plane_z, 0.0, 0.0, 0.0],
            cov: vec![
                vec![pv * c[(0, 0)], pv * c[(0, 1)], 0.0, 0.0],
                vec![pv * c[(1, 0)], pv * c[(1, 1)], 0.0, 0.0],
                vec![0.0, 0.0, vv, 0.0],
                vec![0.0, 0.0, 0.0, vv],
            ],
            cov_dims: Some(vec![0, 1, 3, 4]),
        })
    })
}

/// Scenario sensor ids of the (vehicle, sensor) pairs: `cam1`, or `cam@1` for every sensor when
/// that naming is ambiguous (`cam1` of vehicle 1 and `cam` of vehicle 11).
pub(super) fn sensor_ids(
    sensors: &BTreeMap<(u8, String), SensorEntry>,
) -> BTreeMap<(u8, String), String> {
    let plain: BTreeSet<String> = sensors
        .keys()
        .map(|(v, s)| scenario_out::sensor_id(s, *v))
        .collect();
    let ambiguous = plain.len() < sensors.len();
    sensors
        .keys()
        .map(|k| {
            let id = if ambiguous {
                format!("{}@{}", k.1, k.0)
            } else {
                scenario_out::sensor_id(&k.1, k.0)
            };
            (k.clone(), id)
        })
        .collect()
}

/// The scenario's sensor entry for `e` with id `id` on vehicle `vehicle`'s platform.
fn scenario_sensor(id: &str, vehicle: u8, e: &SensorEntry) -> fmt::Sensor {
    let span = e.times.last().copied().unwrap_or(0.0) - e.times.first().copied().unwrap_or(0.0);
    fmt::Sensor {
        id: id.into(),
        platform: scenario_out::platform_id(vehicle),
        kind: e.kind,
        ncomp: (e.kind == MeasKind::Position).then_some(e.noise_std.len()),
        rate_hz: (e.times.len() > 1 && span > 0.0).then(|| (e.times.len() - 1) as f64 / span),
        noise: fmt::Noise::Gaussian {
            std: e.noise_std.clone(),
        },
        bias: None,
    }
}

/// A ground target of unknown size.
fn ground_target(id: &str) -> fmt::Target {
    fmt::Target {
        id: id.into(),
        size_m: None,
        size_prior: None,
        on_ground: Some(true),
    }
}

/// `measurements.jsonl`: `lines` named by their scenario sensor ids (`ids`) and sorted by time,
/// then sensor id (a scan's detections keep their order).
pub(super) fn measurements_jsonl(
    lines: &mut [Line],
    ids: &BTreeMap<(u8, String), String>,
) -> Result<String, String> {
    for l in lines.iter_mut() {
        l.m.sensor.clone_from(&ids[&l.sensor]);
    }
    lines.sort_by(|a, b| {
        a.m.t
            .total_cmp(&b.m.t)
            .then_with(|| a.m.sensor.cmp(&b.m.sensor))
    });
    let mut out = String::new();
    for l in lines.iter() {
        let text = serde_json::to_string(&l.m)
            .map_err(|e| format!("cannot serialise a measurement: {e}"))?;
        out.push_str(&text);
        out.push('\n');
    }
    Ok(out)
}

/// The scenario's platforms (one per vehicle) and sensors (named by `ids`).
pub(super) fn scenario_sensors(
    sensors: &BTreeMap<(u8, String), SensorEntry>,
    ids: &BTreeMap<(u8, String), String>,
) -> (Vec<fmt::Platform>, Vec<fmt::Sensor>) {
    let vehicles: BTreeSet<u8> = sensors.keys().map(|k| k.0).collect();
    let platforms = vehicles
        .iter()
        .map(|v| fmt::Platform {
            id: scenario_out::platform_id(*v),
            kind: "uav".into(),
        })
        .collect();
    let list = sensors
        .iter()
        .map(|(k, e)| scenario_sensor(&ids[k], k.0, e))
        .collect();
    (platforms, list)
}

/// The shape of an export: its format, its time line and its time axis.
#[derive(Debug)]
pub(super) struct Shape {
    /// FORMAT-MULTI.md rather than single-target.
    pub(super) multi: bool,
    pub(super) line: TimeLine,
    pub(super) times: ScanTimes,
}

/// `scenario.json` of the export of `session` (read from `db`): its platforms and sensors,
/// targets, time axis, the session's motion models and roads, and where it came from.
pub(super) fn scenario_document(
    db: &Path,
    session: &Recorded,
    shape: &Shape,
    (platforms, sensors): (Vec<fmt::Platform>, Vec<fmt::Sensor>),
    targets: &BTreeMap<String, TargetTruth>,
    prior: Option<fmt::Prior>,
) -> fmt::ScenarioDocument {
    let (info, id) = (&session.info, session.info.id);
    let mut extensions = serde_json::Map::new();
    if shape.multi {
        let all: Vec<fmt::Target> = if targets.is_empty() {
            vec![ground_target("unknown")]
        } else {
            targets.keys().map(|k| ground_target(k)).collect()
        };
        extensions.insert("targets".into(), json!(all));
    }
    let (epoch, time_line) = (shape.line.epoch, shape.line.name());
    let scenario = fmt::Scenario {
        format: fmt::FORMAT_ID.into(),
        name: format!("session_{id}"),
        description: format!(
            "harrier serve session {id} of {} (started {:.3} UNIX, track filter {}); time 0 is \
             {epoch:.6} on the {time_line} time line",
            db.display(),
            info.started_unix,
            info.estimator
        ),
        dims: 2,
        plane_z: Some(info.plane_z),
        time: fmt::TimeSpec {
            t0: 0.0,
            dt: shape.times.dt,
            t_end: shape.times.t_end(),
        },
        target: ground_target(if shape.multi {
            "multi"
        } else {
            targets.keys().next().map_or("tgt", String::as_str)
        }),
        platforms,
        sensors,
        roads: session.roads.clone(),
        motion: Some(session.motion.clone()),
        prior,
        linear_system: None,
        hints: json!({}),
        scoring: fmt::Scoring::default(),
        detection: None,
    };
    let generator = fmt::Generator {
        family: "harrier sessions export".into(),
        seed: 0,
        params: json!({
            "session": id,
            "started_unix": info.started_unix,
            "ended_unix": info.ended_unix,
            "estimator": info.estimator,
            "epoch": epoch,
            "time_line": time_line,
            "version": env!("CARGO_PKG_VERSION"),
        }),
    };
    fmt::ScenarioDocument {
        scenario,
        frame: fmt::Frame::enu(Some(session.origin())),
        extensions,
        generator,
    }
}
