//! Live sensor registration: a [`Registrar`] keeps harrier-core's [`BiasBank`] beside the
//! multi-target tracker of a track engine (`[[registration.sensors]]` of the live service,
//! [`Deployment::registration`]).
//!
//! Per scan (in time order; a late, retrodicted scan is refused while registration runs):
//!
//! 1. the bank's biases and track covariances are predicted to the scan time;
//! 2. a registered sensor's detections are corrected ([`BiasBank::correct`]: offsets and scales
//!    taken out) and its noise inflated by the bias uncertainty (the diagonal of `J P_bb Jᵀ`);
//!    with a time offset δ̂ the sensor is placed where its platform was when it took the scan
//!    (`p_s − δ̂ v_s`, [`ScanSource::platform_vel`]) and the noise carries what δ's uncertainty
//!    moves, so that gating, association, initiation and the tentative tracks see de-biased data;
//! 3. a detection within the gate (χ² 0.999) of a cooperative reference
//!    ([`ScanSource::references`]: a UAV whose own GPS position is known) is that UAV's: it
//!    updates the biases ([`BiasBank::update_reference`], the GPS covariance in the noise) and
//!    every bank track through its correlation with them, and it is kept from the tracker (no
//!    track starts or updates on a UAV); each reference takes its nearest detection;
//! 4. the tracker runs the other detections;
//! 5. each detection the tracker associated with a track of the bank (a hard association:
//!    JIPDA's most probable detection) is one joint update of every bank track and every bias
//!    ([`BiasBank::update`]) with the **raw** detection, from the tracks' predicted states; the
//!    bank's track states then replace the tracker's ([`Tracker::recentre`]: a mixture keeps its
//!    mode probabilities, and a road-constrained IMM applies its road update after it, as after
//!    any sensor update; the bank carries the cross-covariances through whatever the tracker did
//!    to a track's covariance, see [`BiasBank`]). Unregistered sensors' detections go through
//!    the bank the same way as unbiased sensors: they fix the targets, and through the
//!    track–bias correlation, the biases. On a planar deployment an angle-only detection that
//!    looks at the ground too flat to range the target (its elevation gives the ground range
//!    with a relative error `σ_el / (sin|el| cos|el|)` over 0.2: a UAV on its take-off roll)
//!    updates the tracker only;
//! 6. a track enters the bank when it is confirmed (uncorrelated with the biases: it was built
//!    from corrected detections), at most [`MAX_BANK_TRACKS`] of them, and leaves when deleted.
//!
//! The bank runs three bias modes, the model as configured, every random-walk term drifting
//! 20 times faster, and no bias ([`BiasBank::with_drift`], [`DriftModes::default`]: the replay
//! estimator's tuning), and the engine reports the bank's tracks weighed over which sensors are
//! biased ([`Registrar::output`], [`BiasBank::output`]): registration then costs nothing on
//! unbiased sensors and follows a drifting bias (BENCHMARKS.md, "The live registrar on the
//! replay scenarios").
//!
//! Without registration the engine holds no registrar and the scan path is the plain one.

use harrier_core::measurement::{
    Geometry, Locate, MeasKind, MeasurementModel, SensorModel, WithSensor,
};
use harrier_core::metrics::chi2_quantile;
use harrier_core::registration::{
    BankOutput, BiasBank, Corrected, DriftModes, KnownObject, Observation, Registration,
    SensorEstimate, TrackId, Tracks, Tuning,
};
use harrier_core::state::Gaussian;
use harrier_core::tracker::{Initiator, TrackEvent, TrackFilter, TrackStatus, Tracker};
use nalgebra::{SVector, Vector3};

use crate::{
    BiasTermView, Deployment, EngineError, Params, RegisteredSensor, ScanSource, SensorBiasView,
    SensorScan, setup,
};

/// The most tracks the bank holds: its cost per detection grows as the square of the tracks it
/// holds (`D = 4 T + n_b`), so the rest are tracked on corrected detections only.
pub const MAX_BANK_TRACKS: usize = 40;

/// The gate probability of a detection of a cooperative reference.
const REFERENCE_GATE: f64 = 0.999;

/// The largest relative error of the ground range an angle-only detection may carry and still
/// update the bank (see [`grazing`]).
const MAX_GROUND_RANGE_ERROR: f64 = 0.2;

/// Whether an angle-only detection `z` (`az_el`, `bearing_size`: elevation `z[1]`, its noise
/// `std[1]`) of a target on the ground plane looks at it too flat for the bank. Its ground range
/// comes from the elevation alone, `r = h / tan|el|` (h the height above the plane), with the
/// relative error `σ_r / r = σ_el / (sin|el| cos|el|)`; above [`MAX_GROUND_RANGE_ERROR`] (4 mrad
/// of noise: |el| below 1.15°) the bank's linearisation fails, and such a detection taken as a
/// joint update of biases and tracks leaves them wrong and over-confident for minutes (a UAV on
/// its take-off roll, a camera near the ground: measured in BENCHMARKS.md, "Latency, live"). The
/// tracker still takes it.
fn grazing(kind: MeasKind, z: &[f64], std: &[f64]) -> bool {
    if !matches!(kind, MeasKind::AzEl | MeasKind::BearingSize) {
        return false;
    }
    let (Some(&el), Some(&sd)) = (z.get(1), std.get(1)) else {
        return false;
    };
    let (s, c) = el.abs().sin_cos();
    !(el.is_finite() && sd.is_finite()) || sd > MAX_GROUND_RANGE_ERROR * s * c
}

/// The bank behind its track state size `K` (its bias capacity erased).
trait LiveBank<const K: usize>: Send + std::fmt::Debug {
    fn predict(&mut self, dt: f64) -> harrier_core::Result<()>;
    fn correct(&self, sensor: usize, z: &[f64]) -> harrier_core::Result<Corrected>;
    fn add_track(&mut self, id: TrackId, track: &Gaussian<K>) -> harrier_core::Result<()>;
    fn remove_track(&mut self, id: TrackId);
    fn tracks(&self) -> &[TrackId];
    fn update(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        id: TrackId,
        obs: &Observation<'_>,
    ) -> harrier_core::Result<f64>;
    fn update_reference(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        obs: &Observation<'_>,
        known: &KnownObject,
    ) -> harrier_core::Result<f64>;
    fn estimates(&self) -> Vec<SensorEstimate>;
    fn output(&self, tracks: &[(TrackId, Gaussian<K>)]) -> harrier_core::Result<BankOutput<K>>;
    fn report(&self) -> harrier_core::Result<(Vec<SensorEstimate>, Vec<f64>)>;
    fn drifting_prob(&self) -> Option<f64>;
    fn unbiased_prob(&self) -> Option<f64>;
}

impl<const K: usize, const N: usize> LiveBank<K> for BiasBank<K, N> {
    fn predict(&mut self, dt: f64) -> harrier_core::Result<()> {
        BiasBank::predict(self, dt)
    }
    fn correct(&self, sensor: usize, z: &[f64]) -> harrier_core::Result<Corrected> {
        BiasBank::correct(self, sensor, z)
    }
    fn add_track(&mut self, id: TrackId, track: &Gaussian<K>) -> harrier_core::Result<()> {
        BiasBank::add_track(self, id, track)
    }
    fn remove_track(&mut self, id: TrackId) {
        BiasBank::remove_track(self, id);
    }
    fn tracks(&self) -> &[TrackId] {
        BiasBank::tracks(self)
    }
    fn update(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        id: TrackId,
        obs: &Observation<'_>,
    ) -> harrier_core::Result<f64> {
        BiasBank::update(self, tracks, id, obs)
    }
    fn update_reference(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        obs: &Observation<'_>,
        known: &KnownObject,
    ) -> harrier_core::Result<f64> {
        BiasBank::update_reference(self, tracks, obs, known)
    }
    fn estimates(&self) -> Vec<SensorEstimate> {
        BiasBank::estimates(self)
    }
    fn output(&self, tracks: &[(TrackId, Gaussian<K>)]) -> harrier_core::Result<BankOutput<K>> {
        BiasBank::output(self, tracks)
    }
    fn report(&self) -> harrier_core::Result<(Vec<SensorEstimate>, Vec<f64>)> {
        BiasBank::report(self)
    }
    fn drifting_prob(&self) -> Option<f64> {
        BiasBank::drifting_prob(self)
    }
    fn unbiased_prob(&self) -> Option<f64> {
        BiasBank::unbiased_prob(self)
    }
}

/// The bank of a track engine with `K`-state tracks and what it needs per scan.
#[derive(Debug)]
pub struct Registrar<const K: usize> {
    bank: Box<dyn LiveBank<K>>,
    /// The registered sensors: the bank's sensors `0..n`; then one unbiased sensor per
    /// measurement size 2 and 3 (indices `n`, `n + 1`) for every other scan.
    sensors: Vec<RegisteredSensor>,
    /// Detections of each registered sensor that updated the bank with a track …
    updates: Vec<u64>,
    /// … and with a cooperative reference.
    references: Vec<u64>,
    /// The geometry of the engine's scans (planar on `plane_z`, or 3-D).
    geometry: Geometry,
    /// Time of the bank.
    t: Option<f64>,
}

/// The registrar of `d` (`None` without registration) with `N − K` bias terms at most;
/// `K`: the engine's track state size.
pub fn registrar<const K: usize, const N: usize>(
    d: &Deployment,
    p: &Params,
) -> Result<Option<Registrar<K>>, EngineError> {
    if d.registration.is_empty() {
        return Ok(None);
    }
    let mut slots = Vec::with_capacity(d.registration.len() + 2);
    for s in &d.registration {
        if s.kind == MeasKind::BearingSize {
            return Err(setup(format!(
                "registration of {}/{}: bearing_size sensors are not registered",
                s.vehicle, s.sensor
            )));
        }
        let dim = s.kind.len(None);
        slots.push((dim, Some(&s.bias)));
    }
    slots.extend([(2, None), (3, None)]);
    let reg = Registration::<K, N>::new(d.q(p)?, d.plane_z, &slots, Tuning::default())
        .map_err(|e| setup(format!("registration: {e}")))?;
    let bank = BiasBank::with_drift(reg, DriftModes::default())
        .map_err(|e| setup(format!("registration: {e}")))?;
    Ok(Some(Registrar {
        bank: Box::new(bank),
        sensors: d.registration.clone(),
        updates: vec![0; d.registration.len()],
        references: vec![0; d.registration.len()],
        geometry: if d.dims == 2 {
            Geometry::planar(d.plane_z)
        } else {
            Geometry::spatial()
        },
        t: None,
    }))
}

impl<const K: usize> Registrar<K> {
    /// The bank's index of the sensor of a scan from `source` of kind `kind` and `dim`
    /// components, and whether it is a registered one.
    fn index(&self, source: &ScanSource<'_>, kind: MeasKind, dim: usize) -> (usize, bool) {
        let n = self.sensors.len();
        match self.sensors.iter().position(|s| {
            s.vehicle == source.vehicle && s.sensor == source.sensor && s.kind == kind
        }) {
            Some(i) => (i, true),
            None => (if dim == 2 { n } else { n + 1 }, false),
        }
    }

    /// A scan's model of `kind` at the source's platform, with noise `std`, in `geometry`.
    fn model(
        kind: MeasKind,
        geometry: Geometry,
        source: &ScanSource<'_>,
        std: &[f64],
    ) -> Result<SensorModel, EngineError> {
        Self::model_at(kind, geometry, source, Vector3::from(source.platform), std)
    }

    /// [`Registrar::model`] with the sensor at `at`.
    fn model_at(
        kind: MeasKind,
        geometry: Geometry,
        source: &ScanSource<'_>,
        at: Vector3<f64>,
        std: &[f64],
    ) -> Result<SensorModel, EngineError> {
        SensorModel::new(kind, geometry, at, std, None)
            .map_err(|e| setup(format!("{}/{}: {e}", source.vehicle, source.sensor)))
    }

    /// One scan through the tracker with registration (see the module docs); returns the
    /// tracker's events.
    pub fn step<F, I>(
        &mut self,
        tracker: &mut Tracker<F, I, K>,
        scan: &SensorScan,
        source: &ScanSource<'_>,
    ) -> Result<Vec<TrackEvent>, EngineError>
    where
        F: TrackFilter<K>,
        I: Initiator<K>,
    {
        let t = scan.t;
        if tracker.time().is_some_and(|t0| t < t0) || self.t.is_some_and(|t0| t < t0) {
            return Err(setup(format!(
                "scan at {t} is older than the last: late scans are not taken with registration"
            )));
        }
        let kind = scan.sensor.kind();
        let dim = scan.sensor.dim();
        if source.noise_std.len() != dim {
            return Err(setup(format!(
                "{}/{}: {} noise components for {dim}-component detections",
                source.vehicle,
                source.sensor,
                source.noise_std.len()
            )));
        }
        if kind == MeasKind::BearingSize {
            // No target size here: such scans pass as they are, outside the bank.
            return Ok(tracker.step_any(t, &scan.sensor, &slices(&scan.detections))?);
        }
        let (sensor, registered) = self.index(source, kind, dim);
        // The raw detections' model for the bank (3-D: the bank puts planar tracks on the plane).
        let raw = Self::model(kind, Geometry::spatial(), source, source.noise_std)?;
        let dt = self.t.map_or(0.0, |t0| t - t0);
        self.bank.predict(dt)?;
        self.t = Some(t);
        // The bank's tracks predicted by the track filter (the tracker predicts the same).
        let dt_tracker = tracker.time().map_or(0.0, |t0| t - t0);
        let mut predicted: Vec<(TrackId, Gaussian<K>)> =
            Vec::with_capacity(self.bank.tracks().len());
        for &id in self.bank.tracks() {
            let k = tracker
                .tracks()
                .iter()
                .find(|k| k.id == id)
                .ok_or_else(|| setup(format!("registration: track {id} is not in the tracker")))?;
            let f = tracker.filter();
            predicted.push((id, f.estimate(&f.predict(&k.state, dt_tracker)?)));
        }
        // Every detection de-biased (a registered sensor's), the model with the inflated noise;
        // with a time offset δ the sensor is where its platform was when it took the scan,
        // `p_s − δ v_s`, and the noise carries what δ's uncertainty moves (the platform's part
        // of the latency: the target's own motion in δ is the bank's to model).
        let (zs, model, gate_model) = if registered {
            let mut std = source.noise_std.to_vec();
            let mut zs = Vec::with_capacity(scan.detections.len());
            let vs = Vector3::from(source.platform_vel);
            let mut at = Vector3::from(source.platform);
            // The fastest bank track's speed: how far a target may have moved in δ̂.
            let fastest = predicted
                .iter()
                .map(|(_, g)| g.mean.rows(K / 2, K / 2).norm())
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max);
            for (i, z) in scan.detections.iter().enumerate() {
                let c = self.bank.correct(sensor, z)?;
                if i == 0 {
                    at -= vs * c.time_offset;
                    let moved = Self::model_at(kind, Geometry::spatial(), source, at, &std)?;
                    let shift = vs * c.time_offset_var.max(0.0).sqrt();
                    let by_latency = moved.apply(Displacement { z: &c.z, shift });
                    // The target's own motion in δ̂, which one model per scan cannot place
                    // (each target moves its own way; the bank's joint update models it per
                    // track): up to the fastest track's speed × |δ̂| along either ground axis,
                    // as noise for the tracker's gating and update. Without it a 200 ms late
                    // camera's detections of a 10 m/s target fell outside the gate of their
                    // own track and started duplicates (BENCHMARKS.md, "The live registrar on
                    // the replay scenarios").
                    let reach = c.time_offset.abs() * fastest;
                    let by_target = [Vector3::x(), Vector3::y()].map(|u| {
                        moved.apply(Displacement {
                            z: &c.z,
                            shift: u * reach,
                        })
                    });
                    for (j, s) in std.iter_mut().enumerate() {
                        let d = by_latency.as_ref().map_or(0.0, |d| d[j]);
                        let m: f64 = by_target
                            .iter()
                            .map(|t| t.as_ref().map_or(0.0, |t| t[j] * t[j]))
                            .sum();
                        *s = (*s * *s + c.extra_cov[(j, j)].max(0.0) + d * d + m).sqrt();
                    }
                }
                zs.push(c.z);
            }
            let model = Self::model_at(kind, self.geometry, source, at, &std)?;
            let gate_model = Self::model_at(kind, Geometry::spatial(), source, at, &std)?;
            (zs, model, gate_model)
        } else {
            let gate_model = Self::model(kind, Geometry::spatial(), source, source.noise_std)?;
            (scan.detections.clone(), scan.sensor, gate_model)
        };
        // Detections of a cooperative reference: the nearest within the gate, each reference
        // taken once; the others go to the tracker, `kept` their indices in the scan.
        let gate = chi2_quantile(REFERENCE_GATE, dim);
        let mut of_reference: Vec<(usize, usize)> = Vec::new();
        for (r, known) in source.references.iter().enumerate() {
            let best = zs
                .iter()
                .enumerate()
                .filter(|(i, _)| !of_reference.iter().any(|(j, _)| j == i))
                .filter_map(|(i, z)| {
                    let d2 = gate_model.apply(ReferenceDistance { known, z })?;
                    (d2 <= gate).then_some((i, d2))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((i, _)) = best {
                of_reference.push((i, r));
            }
        }
        // From here a failure of the bank is reported as an event (the track keeps the
        // tracker's own update), never as a failed scan: the tracker takes the scan.
        let mut rejected = Vec::new();
        // A registered sensor's reference updates its biases (an unbiased sensor's has nothing
        // to tell them); every reference's detection is kept from the tracks.
        let mut moved = false;
        for &(i, r) in of_reference.iter().filter(|_| registered) {
            let obs = Observation {
                sensor,
                model: &raw,
                platform_vel: Vector3::from(source.platform_vel),
                z: &scan.detections[i],
            };
            let mut tracks: Vec<(TrackId, &mut Gaussian<K>)> =
                predicted.iter_mut().map(|(k, g)| (*k, g)).collect();
            match self
                .bank
                .update_reference(&mut tracks, &obs, &source.references[r])
            {
                Ok(_) => {
                    self.references[sensor] += 1;
                    moved = true;
                }
                Err(e) => rejected.push(TrackEvent::Rejected {
                    id: None,
                    detection: Some(i),
                    reason: format!("registration: reference: {e}"),
                }),
            }
        }
        let kept: Vec<usize> = (0..zs.len())
            .filter(|i| !of_reference.iter().any(|(j, _)| j == i))
            .collect();
        let to_track: Vec<&[f64]> = kept.iter().map(|&i| zs[i].as_slice()).collect();
        let mut events = tracker.step_any(t, &model, &to_track)?;
        // Detection indices back to the scan's.
        for e in &mut events {
            if let TrackEvent::Born { detection, .. }
            | TrackEvent::Updated { detection, .. }
            | TrackEvent::Rejected {
                detection: Some(detection),
                ..
            } = e
            {
                *detection = kept.get(*detection).copied().unwrap_or(*detection);
            }
        }
        for e in &events {
            if let TrackEvent::Deleted { id, .. } = e {
                self.bank.remove_track(*id);
                predicted.retain(|(k, _)| k != id);
            }
        }
        // Each detection associated with a bank track: a joint update, from the raw detection.
        for e in &events {
            let &TrackEvent::Updated { id, detection, .. } = e else {
                continue;
            };
            let Some(z) = scan.detections.get(detection) else {
                continue;
            };
            if !predicted.iter().any(|(k, _)| *k == id) {
                continue;
            }
            if !self.geometry.up_in_state && grazing(kind, z, source.noise_std) {
                continue;
            }
            let obs = Observation {
                sensor,
                model: &raw,
                platform_vel: Vector3::from(source.platform_vel),
                z,
            };
            let mut tracks: Vec<(TrackId, &mut Gaussian<K>)> =
                predicted.iter_mut().map(|(k, g)| (*k, g)).collect();
            match self.bank.update(&mut tracks, id, &obs) {
                Ok(_) => {
                    moved = true;
                    if registered {
                        self.updates[sensor] += 1;
                    }
                }
                Err(e) => rejected.push(TrackEvent::Rejected {
                    id: Some(id),
                    detection: Some(detection),
                    reason: format!("registration: {e}"),
                }),
            }
        }
        if moved {
            for (id, g) in &predicted {
                if let Err(e) = tracker.recentre(*id, *g) {
                    rejected.push(TrackEvent::Rejected {
                        id: Some(*id),
                        detection: None,
                        reason: format!("registration: {e}"),
                    });
                }
            }
        }
        // Confirmed tracks enter the bank (also those adopted confirmed from another engine).
        let entering: Vec<(TrackId, Gaussian<K>)> = tracker
            .tracks()
            .iter()
            .filter(|k| k.status == TrackStatus::Confirmed && !self.bank.tracks().contains(&k.id))
            .map(|k| (k.id, tracker.filter().estimate(&k.state)))
            .collect();
        for (id, g) in entering {
            if self.bank.tracks().len() >= MAX_BANK_TRACKS {
                break;
            }
            if let Err(e) = self.bank.add_track(id, &g) {
                rejected.push(TrackEvent::Rejected {
                    id: Some(id),
                    detection: None,
                    reason: format!("registration: {e}"),
                });
            }
        }
        events.extend(rejected);
        Ok(events)
    }

    /// The bank's tracks as they are reported: the tracker's estimates weighed over which
    /// sensors are biased ([`BiasBank::output`]); `None` when the bank cannot weigh them (a
    /// track of the bank not in the tracker, a failed factorisation): the tracker's own stand.
    pub fn output<F, I>(&self, tracker: &Tracker<F, I, K>) -> Option<BankOutput<K>>
    where
        F: TrackFilter<K>,
        I: Initiator<K>,
    {
        let tracks = self
            .bank
            .tracks()
            .iter()
            .map(|&id| {
                let k = tracker.tracks().iter().find(|k| k.id == id)?;
                Some((id, tracker.filter().estimate(&k.state)))
            })
            .collect::<Option<Vec<_>>>()?;
        self.bank.output(&tracks).ok()
    }

    /// The registered sensors' entries of `bias_est`, keyed by sensor id, with the detections
    /// that updated them (`updates`: with a track; `references`: of a cooperative reference).
    pub fn bias_est(&self) -> serde_json::Map<String, serde_json::Value> {
        let (estimates, biased) = self.report();
        let drifting = self.bank.drifting_prob();
        let none = self.bank.unbiased_prob();
        estimates
            .into_iter()
            .zip(&self.sensors)
            .zip(self.updates.iter().zip(&self.references))
            .enumerate()
            .map(|(i, ((e, s), (n, r)))| {
                let mut json = e.to_json();
                json["updates"] = serde_json::json!(n);
                json["references"] = serde_json::json!(r);
                json["biased_prob"] = serde_json::json!(biased.get(i));
                json["bias_drift_prob"] = serde_json::json!(drifting);
                json["bias_none_prob"] = serde_json::json!(none);
                (s.sensor.clone(), json)
            })
            .collect()
    }

    /// The bank's estimates and the probability that each sensor is biased; the estimates
    /// alone (the biased modes') if the hypotheses cannot be weighed.
    fn report(&self) -> (Vec<SensorEstimate>, Vec<f64>) {
        self.bank
            .report()
            .unwrap_or_else(|_| (self.bank.estimates(), Vec::new()))
    }

    /// The registered sensors' estimates.
    pub fn biases(&self) -> Vec<SensorBiasView> {
        let (estimates, biased) = self.report();
        let drift_prob = self.bank.drifting_prob();
        estimates
            .into_iter()
            .zip(&self.sensors)
            .zip(&self.updates)
            .zip(self.references.iter().copied())
            .enumerate()
            .map(|(i, (((e, s), n), r))| SensorBiasView {
                vehicle: s.vehicle.clone(),
                sensor: s.sensor.clone(),
                kind: s.kind.as_str().to_owned(),
                observable: e.observable,
                updates: *n,
                references: r,
                biased_prob: biased.get(i).copied(),
                drift_prob,
                terms: e
                    .terms
                    .iter()
                    .map(|t| BiasTermView {
                        term: t.term.name(),
                        value: t.value,
                        std: t.std,
                        observable: t.observable,
                    })
                    .collect(),
            })
            .collect()
    }
}

/// The normalised distance `νᵀ S⁻¹ ν` of a detection `z` from a known object's predicted
/// measurement under a 3-D model (`S = H Σ Hᵀ + R`); `None` when it cannot be computed.
struct ReferenceDistance<'a> {
    known: &'a KnownObject,
    z: &'a [f64],
}

impl WithSensor<6> for ReferenceDistance<'_> {
    type Output = Option<f64>;
    fn with<H, const M: usize>(self, model: &H) -> Option<f64>
    where
        H: MeasurementModel<6, M> + Locate<M>,
    {
        if self.z.len() != M {
            return None;
        }
        let k = self.known;
        let x = SVector::<f64, 6>::from_column_slice(&[
            k.pos.x, k.pos.y, k.pos.z, k.vel.x, k.vel.y, k.vel.z,
        ]);
        let z = SVector::<f64, M>::from_column_slice(self.z);
        let nu = model.residual(&z, &model.function(&x));
        let h = model.jacobian(&x).fixed_columns::<3>(0).into_owned();
        let s = h * k.cov * h.transpose() + model.covar();
        let d2 = (nu.transpose() * s.try_inverse()? * nu)[0];
        d2.is_finite().then_some(d2)
    }
}

/// How far a displacement `shift` of the sensor moves detection `z` in measurement space, per
/// component (`|H_p shift|` at the position `z` fixes): the spread a latency's uncertainty
/// gives a moving platform's detections.
struct Displacement<'a> {
    z: &'a [f64],
    shift: Vector3<f64>,
}

impl WithSensor<6> for Displacement<'_> {
    type Output = Option<Vec<f64>>;
    fn with<H, const M: usize>(self, model: &H) -> Option<Vec<f64>>
    where
        H: MeasurementModel<6, M> + Locate<M>,
    {
        if self.z.len() != M {
            return None;
        }
        let fix = model.locate(&SVector::<f64, M>::from_column_slice(self.z))?;
        let x =
            SVector::<f64, 6>::from_column_slice(&[fix.pos.x, fix.pos.y, fix.pos.z, 0.0, 0.0, 0.0]);
        let h = model.jacobian(&x).fixed_columns::<3>(0).into_owned();
        let d = h * self.shift;
        d.iter()
            .all(|v| v.is_finite())
            .then(|| d.iter().map(|v| v.abs()).collect())
    }
}

/// The detections as slices.
fn slices(zs: &[Vec<f64>]) -> Vec<&[f64]> {
    zs.iter().map(Vec::as_slice).collect()
}

#[cfg(test)]
#[path = "registrar_tests.rs"]
mod tests;
