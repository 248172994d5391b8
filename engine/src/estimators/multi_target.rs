//! The multi-target tracker of `harrier_core::tracker` (χ² gating through a spatial index,
//! single-point initiation from any detection kind, deletion) as a [`TrackEngine`],
//! `MultiTargetEngine`, one per **track filter** — the filter of each track: `ekf` (the KF on
//! `position` sensors), `cdkf`, `imm`, `cimm` ([`TrackFilterInfo`]s, the live service's choice)
//! — with an **associator** (`gnn`, `jipda`, `mht`: [`associators`](super::associators)), built
//! for a [`Deployment`].
//!
//! The replay estimator `tracker` runs the `ekf` track filter with `gnn` over a multi-target
//! scenario (FORMAT-MULTI.md); [`replay_tracker`] any other pair (`harrier replay -e tracker
//! --track-filter imm --associator jipda`): any number of sensors of any kind whose scans carry
//! unlabeled detections, clutter included. Each sensor's detections of one time are one scan,
//! under that sensor's model at its platform pose. Each estimate line holds every confirmed
//! track after the scan (`"state": null`, `"tracks"`): see FORMAT-MULTI.md §4.

use harrier_core::filter::{CentralDifference, Extended, ModeModel};
use harrier_core::measurement::{MeasKind, SensorModel};
use harrier_core::motion::ConstantVelocity;
use harrier_core::registration::KnownObject;
use harrier_core::road::RoadNetwork;
use harrier_core::scenario::{Estimate, Measurement, Scenario};
use harrier_core::tracker::{
    Association, AssociationStats, CimmFilter, Deleter, Gater, GaussianFilter, ImmFilter, MOfN,
    SinglePointInitiator, TrackFilter, TrackSnapshot, Tracker, TrackerConfig,
};
use serde_json::{Value, json};

use super::registrar::{Registrar, registrar};
use super::{count, cv_estimate, geometry, imm_of, known_object, mode_models, model_for};
use crate::{
    Deployment, EngineError, EstimatorInfo, Handover, Params, Q_PARAM, ReplayEstimator,
    ScanOutcome, ScanSource, SensorBiasView, SensorScan, Step, TrackEngine, TrackFilterInfo,
    TrackView, setup,
};
use harrier_core::state::Gaussian;
use nalgebra::{SMatrix, SVector};

/// `tracker`: GNN multi-target tracker.
pub const TRACKER: EstimatorInfo = EstimatorInfo {
    name: "tracker",
    summary: "multi-target GNN tracker (EKF, CV, χ² gate, M-of-N), any sensors: all confirmed tracks per scan (FORMAT-MULTI.md)",
    params: TRACKER_PARAMS,
    build: |sc, p| {
        let engine = (TRACK_FILTER_EKF.build)(&Deployment::from(sc), p, Association::Gnn)?;
        replay_tracker(sc, engine)
    },
};

/// The replay estimator `tracker` over a track engine built for the scenario (any track filter
/// and associator): refuses a scenario without sensors, or with `bearing_size` sensors and no
/// target size.
pub fn replay_tracker(
    sc: &Scenario,
    engine: Box<dyn TrackEngine>,
) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    if sc.sensors.is_empty() {
        return Err(setup("the tracker needs at least one sensor"));
    }
    if let Some(s) = sc
        .sensors
        .iter()
        .find(|s| s.kind == MeasKind::BearingSize && sc.target.size_m.is_none())
    {
        return Err(setup(format!(
            "sensor {:?}: bearing_size detections need target.size_m to start tracks",
            s.id
        )));
    }
    Ok(Box::new(MultiTracker {
        registers: !engine.biases().is_empty(),
        engine,
        sc: sc.clone(),
        last: None,
    }))
}

/// The state sizes of the registration bank: planar and 3-D tracks with up to 12 bias terms.
const BANK_2D: usize = 16;
const BANK_3D: usize = 18;

type Ekf<const N: usize> = GaussianFilter<Extended, ConstantVelocity<N>>;

/// The tracker's tuning, shared by every track filter and the replay estimator `tracker`.
const TRACKER_PARAMS: &[(&str, &str)] = &[
    Q_PARAM,
    ("vel_std", "velocity prior of a new track, m/s (default 12)"),
    (
        "up_std",
        "height prior of a new 3-D track when its first detection gives none, m (default 50)",
    ),
    (
        "gate",
        "gate probability of confirmed tracks (default 0.999)",
    ),
    (
        "tentative_gate",
        "gate probability of tentative tracks (default 0.95)",
    ),
    ("m", "confirmation: M hits … (default 2)"),
    ("n", "… within the first N scans (default 4)"),
    (
        "misses",
        "consecutive missed scans that delete a confirmed track (default 5 per sensor)",
    ),
    (
        "max_pos_var",
        "position-variance trace that deletes a track, m² (default 1e5)",
    ),
];

/// `ekf`: tracks of EKFs (the KF on `position` sensors) with the CV model.
pub const TRACK_FILTER_EKF: TrackFilterInfo = TrackFilterInfo {
    name: "ekf",
    summary: "EKF tracks, CV model (the KF on position sensors)",
    params: TRACKER_PARAMS,
    build: |d, p, a| match d.dims {
        2 => multi_target_engine::<4, _>(d, p, a, ekf(d, p)?, registrar::<4, BANK_2D>(d, p)?),
        _ => multi_target_engine::<6, _>(d, p, a, ekf(d, p)?, registrar::<6, BANK_3D>(d, p)?),
    },
};

/// `cdkf`: tracks of central-difference filters with the CV model.
pub const TRACK_FILTER_CDKF: TrackFilterInfo = TrackFilterInfo {
    name: "cdkf",
    summary: "central-difference Kalman filter tracks, CV model",
    params: TRACKER_PARAMS,
    build: |d, p, a| {
        let q = d.q(p)?;
        let filter = CentralDifference::default();
        match d.dims {
            2 => multi_target_engine::<4, _>(
                d,
                p,
                a,
                GaussianFilter {
                    filter,
                    motion: ConstantVelocity::<4>::new(q),
                },
                registrar::<4, BANK_2D>(d, p)?,
            ),
            _ => multi_target_engine::<6, _>(
                d,
                p,
                a,
                GaussianFilter {
                    filter,
                    motion: ConstantVelocity::<6>::new(q),
                },
                registrar::<6, BANK_3D>(d, p)?,
            ),
        }
    },
};

/// `imm`: IMM tracks over `motion.models` (planar).
pub const TRACK_FILTER_IMM: TrackFilterInfo = TrackFilterInfo {
    name: "imm",
    summary: "IMM tracks (CV / known-rate CT modes from motion.models, EKF mode filters), planar",
    params: TRACKER_PARAMS,
    build: |d, p, a| imm_engine(d, p, a, None),
};

/// `cimm`: road-constrained IMM tracks (\[CIMM\]) over `motion.models` and `roads` (planar).
pub const TRACK_FILTER_CIMM: TrackFilterInfo = TrackFilterInfo {
    name: "cimm",
    summary: "road-constrained IMM tracks ([CIMM]) on the roads, off-road targets unconstrained, planar",
    params: TRACKER_PARAMS,
    build: |d, p, a| {
        let roads = RoadNetwork::from_scenario(&d.roads)
            .map_err(|e| setup(format!("scenario.json roads: {e}")))?;
        if roads.is_empty() {
            return Err(setup("the cimm track filter needs roads"));
        }
        imm_engine(d, p, a, Some(roads))
    },
};

fn ekf<const N: usize>(d: &Deployment, p: &Params) -> Result<Ekf<N>, EngineError> {
    Ok(GaussianFilter {
        filter: Extended,
        motion: ConstantVelocity::<N>::new(d.q(p)?),
    })
}

/// The IMM (or, with roads, CIMM) engine for R = the number of `motion.models`.
fn imm_engine(
    d: &Deployment,
    p: &Params,
    a: Association,
    roads: Option<RoadNetwork>,
) -> Result<Box<dyn TrackEngine>, EngineError> {
    if d.dims != 2 {
        return Err(setup("the IMM track filters are planar (dims = 2)"));
    }
    let models = mode_models(d.motion.as_ref(), d.q(p)?)?;
    fn boxed<const R: usize>(
        d: &Deployment,
        p: &Params,
        a: Association,
        models: &[ModeModel],
        roads: Option<RoadNetwork>,
    ) -> Result<Box<dyn TrackEngine>, EngineError> {
        let (imm, initial_probs) = imm_of::<R>(d.motion.as_ref(), models)?;
        let imm = ImmFilter { imm, initial_probs };
        let reg = registrar::<4, BANK_2D>(d, p)?;
        match roads {
            None => multi_target_engine::<4, _>(d, p, a, imm, reg),
            Some(roads) => {
                let sigma_m = roads
                    .roads()
                    .iter()
                    .map(|r| r.sigma_m())
                    .fold(0.0, f64::max);
                let cimm = CimmFilter {
                    imm,
                    roads,
                    sigma_v: sigma_m / d.scan_period_s.max(1e-3),
                    max_offset_m: 3.0 * sigma_m + 10.0,
                };
                multi_target_engine::<4, _>(d, p, a, cimm, reg)
            }
        }
    }
    match models.len() {
        1 => boxed::<1>(d, p, a, &models, roads),
        2 => boxed::<2>(d, p, a, &models, roads),
        3 => boxed::<3>(d, p, a, &models, roads),
        4 => boxed::<4>(d, p, a, &models, roads),
        5 => boxed::<5>(d, p, a, &models, roads),
        n => Err(setup(format!(
            "motion.models has {n} models; the IMM track filters support 1 to 5"
        ))),
    }
}

/// A multi-target tracker over the track filter `F` on N-state CV-layout states: the
/// [`TrackEngine`] every track filter builds.
#[derive(Debug)]
struct MultiTargetEngine<F: TrackFilter<N>, const N: usize> {
    tracker: Tracker<F, SinglePointInitiator, N>,
    /// The ground plane of planar tracks (their estimate lines' z).
    plane_z: f64,
    /// The clutter density of every scan (`--param clutter_density`), else …
    clutter_param: Option<f64>,
    /// … that of planar `position` scans ([`Deployment::ground_clutter_density`]); other scans'
    /// is estimated from the scan.
    position_clutter: Option<f64>,
    /// Live sensor registration, when the deployment has it.
    registrar: Option<Registrar<N>>,
}

impl<F: TrackFilter<N>, const N: usize> MultiTargetEngine<F, N> {
    /// The clutter density of `scan`'s association (`None`: estimated from the scan).
    fn clutter_density(&self, scan: &SensorScan) -> Option<f64> {
        let planar_position = matches!(scan.sensor, SensorModel::Position2(_));
        self.clutter_param
            .or(self.position_clutter.filter(|_| planar_position))
    }

    /// The engine's view of harrier-core's snapshot of a track.
    fn view(&self, k: TrackSnapshot<N>) -> TrackView {
        let e = cv_estimate(self.plane_z, k.t, &k.estimate);
        TrackView {
            id: k.id,
            status: k.status.into(),
            t: k.t,
            state: e.state.unwrap_or_default(),
            cov: e.cov.unwrap_or_default(),
            cov_dims: e.cov_dims.unwrap_or_default(),
            updated: k.updated,
            age: k.age,
            last_update: k.last_update,
            mode_probabilities: k.mode_probabilities,
            existence: k.existence,
        }
    }
}

/// The engine over `filter` with the tracker tuning of `p` and the associator `association`.
fn multi_target_engine<const N: usize, F>(
    d: &Deployment,
    p: &Params,
    association: Association,
    filter: F,
    registrar: Option<Registrar<N>>,
) -> Result<Box<dyn TrackEngine>, EngineError>
where
    F: TrackFilter<N> + Send + std::fmt::Debug + 'static,
    F::State: Send,
{
    if registrar.is_some() && matches!(association, Association::Mht(_)) {
        return Err(setup(
            "registration runs with the single-scan associators (gnn, jipda), not mht",
        ));
    }
    let init = SinglePointInitiator::new(p.get("vel_std", 12.0), p.get("up_std", 50.0))?;
    // Every sensor's scan counts as a scan for M-of-N and misses.
    let config = TrackerConfig {
        gater: Gater::chi2(p.get("gate", 0.999), 2)?,
        tentative_gater: Gater::chi2(p.get("tentative_gate", 0.95), 2)?,
        confirm: MOfN::new(count(p, "m", 2)?, count(p, "n", 4)?)?,
        deleter: Deleter::new(
            count(p, "misses", 5 * d.sensors)?,
            p.get("max_pos_var", 1e5),
            usize::from(d.dims),
        )?,
        association,
    };
    Ok(Box::new(MultiTargetEngine {
        tracker: Tracker::new(filter, init, config),
        plane_z: d.plane_z,
        clutter_param: p.opt("clutter_density"),
        position_clutter: d.ground_clutter_density(),
        registrar,
    }))
}

impl<F, const N: usize> TrackEngine for MultiTargetEngine<F, N>
where
    F: TrackFilter<N> + Send + std::fmt::Debug,
    F::State: Send,
{
    fn ingest(&mut self, scan: &SensorScan) -> Result<ScanOutcome, EngineError> {
        self.tracker.set_clutter_density(self.clutter_density(scan));
        let dets: Vec<&[f64]> = scan.detections.iter().map(Vec::as_slice).collect();
        let events = self.tracker.step_any(scan.t, &scan.sensor, &dets)?;
        // `Tracker::step` changes every track it keeps: `scans` + 1 (the view's `age`), the time
        // (`t`), the prediction to it, then the update or the miss. So the changed views are all
        // the live ones (the deleted are gone from the tracker).
        Ok(ScanOutcome {
            events,
            changed: self.snapshot(),
        })
    }

    fn ingest_from(
        &mut self,
        scan: &SensorScan,
        source: &ScanSource<'_>,
    ) -> Result<ScanOutcome, EngineError> {
        let density = self.clutter_density(scan);
        let Some(reg) = self.registrar.as_mut() else {
            return self.ingest(scan);
        };
        self.tracker.set_clutter_density(density);
        let events = reg.step(&mut self.tracker, scan, source)?;
        Ok(ScanOutcome {
            events,
            changed: self.snapshot(),
        })
    }

    fn biases(&self) -> Vec<SensorBiasView> {
        self.registrar
            .as_ref()
            .map_or_else(Vec::new, Registrar::biases)
    }

    fn bias_est(&self) -> serde_json::Map<String, Value> {
        self.registrar
            .as_ref()
            .map_or_else(serde_json::Map::new, Registrar::bias_est)
    }

    /// The tracker's tracks; with registration the bank's as the registrar reports them
    /// (weighed over which sensors are biased, [`Registrar::output`]).
    fn snapshot(&self) -> Vec<TrackView> {
        let registered = self
            .registrar
            .as_ref()
            .and_then(|r| r.output(&self.tracker))
            .map(|o| o.tracks)
            .unwrap_or_default();
        self.tracker
            .snapshot()
            .into_iter()
            .map(|mut k| {
                if let Some((_, g)) = registered.iter().find(|(id, _)| *id == k.id) {
                    k.estimate = *g;
                }
                self.view(k)
            })
            .collect()
    }

    fn time(&self) -> Option<f64> {
        self.tracker.time()
    }

    fn handover(&self) -> Handover {
        Handover {
            t: self.tracker.time(),
            dim: N,
            tracks: self
                .tracker
                .records()
                .into_iter()
                .zip(self.tracker.snapshot())
                .map(|(r, s)| {
                    let cov = s.estimate.cov.transpose().as_slice().to_vec();
                    (r, s.estimate.mean.as_slice().to_vec(), cov)
                })
                .collect(),
        }
    }

    fn adopt(&mut self, h: &Handover) -> Result<(), EngineError> {
        if h.dim != N {
            return Err(setup(format!(
                "cannot adopt {}-state tracks into a {N}-state engine",
                h.dim
            )));
        }
        let Some(t) = h.t else {
            return Ok(());
        };
        let mut tracks = Vec::with_capacity(h.tracks.len());
        for (record, mean, cov) in &h.tracks {
            if mean.len() != N || cov.len() != N * N {
                return Err(setup(format!(
                    "track {}: estimate of the wrong size",
                    record.id
                )));
            }
            let g = Gaussian::new(
                SVector::<f64, N>::from_column_slice(mean),
                SMatrix::<f64, N, N>::from_row_slice(cov),
            )?;
            tracks.push((record.clone(), g));
        }
        Ok(self.tracker.adopt(t, &tracks)?)
    }

    fn association(&self) -> AssociationStats {
        self.tracker.stats()
    }

    fn set_retrodiction_lag(&mut self, lag: f64) -> Result<(), EngineError> {
        if self.registrar.is_some() && lag > 0.0 {
            return Err(setup(
                "late scans are not retrodicted while registration runs",
            ));
        }
        Ok(self.tracker.set_retrodiction_lag(lag)?)
    }
}

/// The replay estimator `tracker`: a track engine (the `ekf` track filter and `gnn`, or any pair
/// [`replay_tracker`] was given), fed one scan per sensor and time. With registration (the
/// engine's deployment registers sensors: `harrier replay -e tracker --register`) each scan
/// goes with its source (platform pose, and the step's cooperative references of its sensor,
/// their detections in the scan), and each estimate line carries `bias_est`.
#[derive(Debug)]
struct MultiTracker {
    engine: Box<dyn TrackEngine>,
    sc: Scenario,
    /// Whether the engine registers sensors (it takes references and writes `bias_est`).
    registers: bool,
    /// The last scan, for the empty scans between measurement lines.
    last: Option<ReplayScan>,
}

/// One sensor's scan of a replay step with where it comes from ([`ScanSource`], owned).
#[derive(Debug, Clone)]
struct ReplayScan {
    scan: SensorScan,
    vehicle: String,
    sensor: String,
    platform: [f64; 3],
    platform_vel: [f64; 3],
    noise_std: Vec<f64>,
    references: Vec<KnownObject>,
}

impl ReplayScan {
    /// An empty scan of the line `m`'s sensor at its platform pose.
    fn of(sc: &Scenario, m: &Measurement) -> Result<Self, EngineError> {
        let s = sc
            .sensor(&m.sensor)
            .ok_or_else(|| setup(format!("unknown sensor {:?}", m.sensor)))?;
        Ok(Self {
            scan: SensorScan {
                t: m.t,
                sensor: model_for(sc, geometry(sc), m, None)?,
                detections: Vec::new(),
            },
            vehicle: s.platform.clone(),
            sensor: s.id.clone(),
            platform: m.platform.pos,
            platform_vel: m.platform.vel,
            noise_std: s.noise.std(),
            references: Vec::new(),
        })
    }

    fn source(&self) -> ScanSource<'_> {
        ScanSource {
            vehicle: &self.vehicle,
            sensor: &self.sensor,
            platform: self.platform,
            platform_vel: self.platform_vel,
            noise_std: &self.noise_std,
            references: &self.references,
        }
    }
}

impl ReplayEstimator for MultiTracker {
    fn association(&self) -> Option<AssociationStats> {
        Some(self.engine.association())
    }

    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        // One scan per sensor (measurements come sorted by sensor id).
        let mut scans: Vec<ReplayScan> = Vec::new();
        for m in step.measurements {
            if scans.last().is_none_or(|s| s.sensor != m.sensor) {
                scans.push(ReplayScan::of(&self.sc, m)?);
            }
            if let Some(s) = scans.last_mut() {
                s.scan.detections.push(m.z.clone());
            }
        }
        // With registration, a cooperative reference's detection joins its sensor's scan of the
        // same time (or makes one), the reference beside it.
        if self.registers {
            for r in step.references {
                let m = &r.measurement;
                let i = match scans
                    .iter()
                    .position(|s| s.sensor == m.sensor && (s.scan.t - m.t).abs() < 1e-9)
                {
                    Some(i) => i,
                    None => {
                        scans.push(ReplayScan::of(&self.sc, m)?);
                        scans.len() - 1
                    }
                };
                scans[i].scan.detections.push(m.z.clone());
                scans[i].references.push(known_object(&r.object));
            }
            scans.sort_by(|a, b| a.scan.t.total_cmp(&b.scan.t));
        }
        // Scans without any detection have no measurement line: run them as empty scans so that
        // the M-of-N and miss counts see them (scan times t0 + k·dt, FORMAT-MULTI.md §3; the
        // last scan's sensor's own period where its `rate_hz` makes it longer than `dt`, as a
        // 1 Hz radar's in a registration scenario of 0.2 s steps).
        let mut all = Vec::new();
        if let (Some(last), Some(model)) = (self.engine.time(), self.last.as_ref()) {
            let dt = self
                .sc
                .sensor(&model.sensor)
                .and_then(|s| s.rate_hz)
                .filter(|r| *r > 0.0)
                .map_or(self.sc.time.dt, |r| (1.0 / r).max(self.sc.time.dt));
            let gap = ((step.t - last) / dt - 0.5).floor().clamp(0.0, 1e6) as u32;
            all.extend((1..=gap).map(|k| {
                let mut empty = model.clone();
                empty.scan.t = last + f64::from(k) * dt;
                empty.scan.detections.clear();
                empty.references.clear();
                empty
            }));
        }
        // Check every scan before the first is ingested, so that a bad step changes nothing.
        for s in &scans {
            if let Some(z) = s
                .scan
                .detections
                .iter()
                .find(|z| z.len() != s.scan.sensor.dim())
            {
                return Err(setup(format!(
                    "a measurement has {} components, its sensor {}",
                    z.len(),
                    s.scan.sensor.dim()
                )));
            }
        }
        all.extend(scans);
        for s in &all {
            self.engine.ingest_from(&s.scan, &s.source())?;
        }
        if let Some(s) = all.pop() {
            self.last = Some(s);
        }
        let tracks: Vec<Value> = self
            .engine
            .snapshot()
            .into_iter()
            .filter(|k| k.status == crate::TrackStatus::Confirmed)
            .map(|k| {
                json!({
                    "id": k.id,
                    "state": k.state,
                    "cov": k.cov,
                    "cov_dims": k.cov_dims,
                    "updated": k.updated,
                })
            })
            .collect();
        let mut est = Estimate {
            t: step.t,
            ..Estimate::default()
        };
        est.extra.insert("tracks".into(), Value::Array(tracks));
        if self.registers {
            est.extra
                .insert("bias_est".into(), Value::Object(self.engine.bias_est()));
        }
        Ok(Some(est))
    }
}

#[cfg(test)]
mod tests {
    use harrier_core::measurement::{Geometry, MeasKind};
    use harrier_core::scenario::{Motion, Road};
    use harrier_core::tracker::TrackEvent;
    use harrier_core::tracker::generate::{GenConfig, generate};
    use nalgebra::Vector3;
    use serde_json::json;

    use super::*;
    use crate::AssociatorInfo;
    use crate::registry::{ASSOCIATORS, TRACK_FILTERS};

    /// A planar deployment for every track filter: CV and two CT modes (`imm`, `cimm`), a road
    /// across the region (`cimm`), 1 s scans from two sensors.
    fn deployment() -> Deployment {
        let motion: Motion = serde_json::from_value(json!({
            "models": [{"name": "CV", "type": "CV"},
                       {"name": "right", "type": "CT", "turn_rate": -0.02},
                       {"name": "left", "type": "CT", "turn_rate": 0.02}],
            "accel_std": 0.3,
        }))
        .expect("motion");
        let road: Road = serde_json::from_value(json!({
            "id": "r", "sigma_m": 2.0,
            "segments": [{"type": "line", "start": [-3000.0, -2000.0], "end": [3000.0, 2500.0]}],
        }))
        .expect("a road");
        Deployment {
            motion: Some(motion),
            roads: vec![road],
            ..Deployment::planar(2)
        }
    }

    /// harrier-core's seeded multi-target scenario (six targets crossing in pairs, Pd 0.9, 10 m
    /// noise, three clutter detections a scan), each time's detections sent as two scans of that
    /// time (the even and the odd ones), as two sensors would: the second one is not predicted.
    fn scans(seed: u64) -> Vec<SensorScan> {
        let config = GenConfig {
            clutter_rate: 3.0,
            ..GenConfig::default()
        };
        let g = generate(seed, &config).expect("a scenario");
        let sensor = SensorModel::new(
            MeasKind::Position,
            Geometry::planar(0.0),
            Vector3::zeros(),
            &[10.0, 10.0],
            None,
        )
        .expect("a position sensor");
        let mut times: Vec<(f64, Vec<Vec<f64>>)> = Vec::new();
        for line in g.measurements_jsonl.lines() {
            let v: serde_json::Value = serde_json::from_str(line).expect("a line");
            let t = v["t"].as_f64().expect("t");
            let z: Vec<f64> = serde_json::from_value(v["z"].clone()).expect("z");
            match times.last_mut() {
                Some((t0, zs)) if *t0 == t => zs.push(z),
                _ => times.push((t, vec![z])),
            }
        }
        times
            .into_iter()
            .flat_map(|(t, zs)| {
                let (even, odd): (Vec<_>, Vec<_>) =
                    zs.into_iter().enumerate().partition(|(i, _)| i % 2 == 0);
                [even, odd].map(|half| SensorScan {
                    t,
                    sensor,
                    detections: half.into_iter().map(|(_, z)| z).collect(),
                })
            })
            .collect()
    }

    /// The list the live service keeps from the outcomes equals the engine's snapshot after
    /// every scan, for every track filter and associator, through births, confirmations,
    /// updates, misses and deletions, and after a change of track filter and associator
    /// half-way (the list restarts from the new engine's snapshot, as the tracker actor does;
    /// the ids are kept).
    #[test]
    fn the_changed_views_keep_the_track_list_equal_to_the_snapshot() {
        let d = deployment();
        let scans = scans(11);
        assert!(scans.len() > 300, "{} scans", scans.len());
        // Each time's detections come as two scans, so a target is in one of them: P_D 0.45
        // per scan for the associators that take it.
        let params = |a: &AssociatorInfo| {
            if a.params.iter().any(|p| p.0 == "pd") {
                Params::default().with("pd", 0.45)
            } else {
                Params::default()
            }
        };
        for (f, info) in TRACK_FILTERS.iter().enumerate() {
            for (a, assoc) in ASSOCIATORS.iter().enumerate() {
                let name = format!("{} + {}", info.name, assoc.name);
                let p = params(assoc);
                let mut engine =
                    (info.build)(&d, &p, (assoc.build)(&d, &p).expect(&name)).expect(&name);
                let mut tracks = engine.snapshot();
                let mut seen = [0usize; 5];
                for (i, scan) in scans.iter().enumerate() {
                    if i == scans.len() / 2 {
                        let next = &TRACK_FILTERS[(f + 1) % TRACK_FILTERS.len()];
                        let other_assoc = &ASSOCIATORS[(a + 1) % ASSOCIATORS.len()];
                        let q = params(other_assoc);
                        let mut other =
                            (next.build)(&d, &q, (other_assoc.build)(&d, &q).expect(&name))
                                .expect(next.name);
                        other.adopt(&engine.handover()).expect("a handover");
                        let ids = |e: &dyn TrackEngine| -> Vec<u64> {
                            e.snapshot().iter().map(|k| k.id).collect()
                        };
                        assert_eq!(ids(other.as_ref()), ids(engine.as_ref()), "{name}");
                        engine = other;
                        tracks = engine.snapshot();
                    }
                    let outcome = engine.ingest(scan).expect("a scan");
                    let ids: Vec<u64> = outcome.changed.iter().map(|k| k.id).collect();
                    assert!(ids.is_sorted(), "{name}: changed views out of order");
                    let (after, events) = outcome.apply(&tracks);
                    tracks = after;
                    assert_eq!(tracks, engine.snapshot(), "{name}, scan {i}");
                    for e in &events {
                        let kind = match e {
                            TrackEvent::Born { .. } => 0,
                            TrackEvent::Confirmed { .. } => 1,
                            TrackEvent::Updated { .. } => 2,
                            TrackEvent::Coasted { .. } => 3,
                            TrackEvent::Deleted { .. } => 4,
                            TrackEvent::Rejected { .. } => continue,
                        };
                        seen[kind] += 1;
                    }
                }
                // Every kind of change happened (born, confirmed, updated, coasted, deleted).
                assert!(seen.iter().all(|&n| n > 0), "{name}: {seen:?}");
                assert!(
                    tracks
                        .iter()
                        .filter(|k| k.status == crate::TrackStatus::Confirmed)
                        .count()
                        >= 4,
                    "{name}: {} tracks",
                    tracks.len()
                );
            }
        }
    }
}
