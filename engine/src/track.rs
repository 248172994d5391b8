//! The live shape: a multi-target tracker whose track filter type is erased ([`TrackEngine`]),
//! fed one [`SensorScan`] at a time, reporting [`TrackView`]s, handing its tracks over to another
//! ([`Handover`]); built for a [`Deployment`] by a named track filter ([`TrackFilterInfo`]).

use harrier_core::scenario::{DetectionSpec, Motion, Road, Scenario};
use harrier_core::tracker::Association;

use crate::error::EngineError;
use crate::replay::Params;

/// The setting a track engine is built for, and everything a track engine reads of it: where
/// the targets move, how, and how often scans come. The live service makes it from its
/// configuration (`Config::deployment`), `harrier replay -e tracker` from the scenario
/// ([`Deployment::from`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Deployment {
    /// 2: planar targets on the ground plane (states `[x, y, vx, vy]`); 3: targets in 3-D.
    pub dims: u8,
    /// Up coordinate (m) of the ground plane of a planar deployment.
    pub plane_z: f64,
    /// Motion hints (`gcs-scenario/1` `motion`): `accel_std` gives the default `q`; `models`,
    /// `transition_matrix` and `initial_probs` the modes of the IMM track filters.
    pub motion: Option<Motion>,
    /// The road network (`gcs-scenario/1` `roads`) of the road-constrained track filter (`cimm`).
    pub roads: Vec<Road>,
    /// Nominal scan period (s): CIMM's road velocity noise is a road's σ over it.
    pub scan_period_s: f64,
    /// The sensors whose scans feed the tracker (≥ 1). Every sensor's scan counts as a scan for
    /// M-of-N and misses, so the default `misses` is 5 per sensor. The live service, whose
    /// sensors come and go, counts one.
    pub sensors: u32,
    /// What the sensors are known to do (FORMAT-MULTI.md `detection`): the soft and multi-scan
    /// associators take `P_D` from it, and the clutter density of planar `position` scans
    /// (`clutter_rate` over the region's area).
    pub detection: Option<DetectionSpec>,
    /// Live sensor registration: the sensors whose biases the tracker estimates jointly with
    /// its tracks ([`RegisteredSensor`]); empty: off (no bias is estimated, no work is done).
    pub registration: Vec<RegisteredSensor>,
}

#[cfg(test)]
impl Deployment {
    /// A planar deployment on the plane z = 0 with `sensors` sensors, 1 s scans and nothing
    /// else known (no motion, roads, detection block or registration): the tests' base.
    pub(crate) fn planar(sensors: u32) -> Self {
        Self {
            dims: 2,
            plane_z: 0.0,
            motion: None,
            roads: Vec::new(),
            scan_period_s: 1.0,
            sensors,
            detection: None,
            registration: Vec::new(),
        }
    }
}

/// A sensor whose biases the live tracker estimates (`[[registration.sensors]]`): which scans
/// are its (`vehicle`, `sensor`), their kind, and its bias terms with their priors
/// (FORMAT-REGISTRATION.md §1).
#[derive(Debug, Clone, PartialEq)]
pub struct RegisteredSensor {
    /// Vehicle label of its scans.
    pub vehicle: String,
    /// Sensor id of its scans on the vehicle.
    pub sensor: String,
    /// Measurement kind of its scans (`position`, `range_bearing`, `az_el`).
    pub kind: harrier_core::measurement::MeasKind,
    /// Its bias terms and their priors.
    pub bias: harrier_core::registration::SensorBias,
}

impl RegisteredSensor {
    /// The sensors of a scenario with a `bias` block that has terms (FORMAT-REGISTRATION.md §1),
    /// each under its platform's id as the vehicle: what `harrier replay -e tracker --register`
    /// registers, as `[[registration.sensors]]` does live. Errors name the sensor.
    pub fn of_scenario(sc: &Scenario) -> Result<Vec<Self>, EngineError> {
        let mut out = Vec::new();
        for s in &sc.sensors {
            let Some(block) = &s.bias else { continue };
            let bias = harrier_core::registration::SensorBias::from_block(block, s.dim())
                .map_err(|e| crate::setup(format!("sensor {:?}: {e}", s.id)))?;
            if let Some(bias) = bias {
                out.push(Self {
                    vehicle: s.platform.clone(),
                    sensor: s.id.clone(),
                    kind: s.kind,
                    bias,
                });
            }
        }
        Ok(out)
    }
}

/// Where a scan comes from, for sensor registration ([`TrackEngine::ingest_from`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanSource<'a> {
    /// Vehicle label.
    pub vehicle: &'a str,
    /// Sensor id on the vehicle.
    pub sensor: &'a str,
    /// Platform position (ENU, m, the engine's frame).
    pub platform: [f64; 3],
    /// Platform velocity (ENU, m/s): with a sensor's time offset δ, where the platform was δ
    /// before the scan's time (registration's `p_s(t − δ) ≈ p_s − δ v_s`).
    pub platform_vel: [f64; 3],
    /// Per-component noise standard deviations of the detections.
    pub noise_std: &'a [f64],
    /// Cooperative references at the scan's time: the UAVs whose own GPS position is known
    /// (ENU, with its covariance). A detection within the gate of one is that UAV, not a
    /// target: with registration it updates the sensor's biases and no track.
    pub references: &'a [harrier_core::registration::KnownObject],
}

/// One bias term's estimate ([`SensorBiasView::terms`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct BiasTermView {
    /// The term: `offset<i>`, `scale<i>` (component `i` of the sensor's measurement, e.g.
    /// `offset0`) or `time_offset`.
    pub term: String,
    /// Estimate (offsets in the component's unit: m, rad; scales dimensionless; s).
    pub value: f64,
    /// Its standard deviation.
    pub std: f64,
    /// Whether the data determine it: its standard deviation is at most κ = 0.3 times its
    /// prior's.
    pub observable: bool,
}

/// A registered sensor's bias estimate as the live tracker holds it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct SensorBiasView {
    /// Vehicle label of its scans.
    pub vehicle: String,
    /// Sensor id on the vehicle.
    pub sensor: String,
    /// Measurement kind.
    pub kind: String,
    /// Whether every term is observable (the smallest eigenvalue of the sensor's normalised
    /// information against 1/κ²).
    pub observable: bool,
    /// Its detections that updated the biases with a track (targets of opportunity).
    pub updates: u64,
    /// Its detections of a cooperative reference (a UAV whose GPS position is known) that
    /// updated the biases.
    pub references: u64,
    /// The probability that it is biased at all (the registrar's hypotheses of which sensors
    /// are biased, none included; FORMAT-REGISTRATION.md §4).
    pub biased_prob: Option<f64>,
    /// The probability of the registrar's drifting bias mode (the same for every sensor).
    pub drift_prob: Option<f64>,
    /// Each term.
    pub terms: Vec<BiasTermView>,
}

impl Deployment {
    /// The `q` (m²/s³) of the kinematic models: `p`'s `q`, else `motion.accel_std²`.
    pub fn q(&self, p: &Params) -> Result<f64, EngineError> {
        p.q_or(self.motion.as_ref().and_then(Motion::accel_q))
    }

    /// The clutter density of planar `position` scans: `detection.clutter_rate` over the area
    /// of `detection.region`, when both are given and positive.
    pub fn ground_clutter_density(&self) -> Option<f64> {
        let d = self.detection.as_ref()?;
        let area = d.region?.area();
        (d.clutter_rate > 0.0 && area > 0.0 && self.dims == 2).then(|| d.clutter_rate / area)
    }
}

/// A scenario's deployment: its `dims`, `plane_z`, `motion`, `roads`, `time.dt`, number of
/// sensors and `detection` block.
impl From<&Scenario> for Deployment {
    fn from(sc: &Scenario) -> Self {
        Self {
            dims: sc.dims,
            plane_z: sc.plane_z(),
            motion: sc.motion.clone(),
            roads: sc.roads.clone(),
            scan_period_s: sc.time.dt,
            sensors: u32::try_from(sc.sensors.len().max(1)).unwrap_or(u32::MAX),
            detection: sc.detection.clone(),
            registration: Vec::new(),
        }
    }
}

/// One sensor scan as a track engine takes it, in the engine's local ENU frame: the time, the
/// sensor's measurement model at the platform pose of the scan (kind, position, noise), and the
/// detections, each with the model's number of components. This is what the live service makes
/// of a `DetectionScan` and what `harrier replay` makes of one sensor's measurement lines of one
/// time.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorScan {
    /// Scan time (s).
    pub t: f64,
    /// Measurement model of the sensor at this scan.
    pub sensor: harrier_core::measurement::SensorModel,
    /// The detections (clutter included), each a measurement vector.
    pub detections: Vec<Vec<f64>>,
}

/// Life-cycle stage of a live track: `tentative` (not yet through the M-of-N rule) or
/// `confirmed` (reported). The wire spelling is the snake-case name.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, utoipa::ToSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum TrackStatus {
    /// Started by an unassociated detection, not yet confirmed.
    Tentative,
    /// Confirmed by the M-of-N rule.
    Confirmed,
}

impl TrackStatus {
    /// `"tentative"` or `"confirmed"` (as on the wire; the recording's `status` column).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Tentative => "tentative",
            Self::Confirmed => "confirmed",
        }
    }
}

impl From<harrier_core::tracker::TrackStatus> for TrackStatus {
    fn from(s: harrier_core::tracker::TrackStatus) -> Self {
        match s {
            harrier_core::tracker::TrackStatus::Tentative => Self::Tentative,
            harrier_core::tracker::TrackStatus::Confirmed => Self::Confirmed,
        }
    }
}

/// What a track engine reports of one track: the estimate in the canonical state layout of an
/// estimate line (`[x, y, z, vx, vy, vz]`, FORMAT.md §5) with its covariance over `cov_dims`.
/// Not a wire type: the API sends it as a `harrier_server::wire::TrackDto`.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackView {
    /// Stable track id.
    pub id: u64,
    /// Tentative or confirmed.
    pub status: TrackStatus,
    /// Time of the estimate (s).
    pub t: f64,
    /// `[x, y, z, vx, vy, vz]` (planar: z = the ground plane, vz = 0).
    pub state: [f64; 6],
    /// Covariance over the state indices `cov_dims`.
    pub cov: Vec<Vec<f64>>,
    /// The state indices `cov` covers.
    pub cov_dims: Vec<usize>,
    /// Whether the last scan updated the track (`false`: it coasted).
    pub updated: bool,
    /// Scans since initiation.
    pub age: u32,
    /// Time of the last associated detection (s).
    pub last_update: f64,
    /// Mode probabilities of an IMM track (empty otherwise).
    pub mode_probabilities: Vec<f64>,
    /// Probability of existence (the `jipda` and `mht` associators; `None` under `gnn`). Not
    /// recorded: a session's tracks read back have none.
    pub existence: Option<f64>,
}

impl TrackView {
    /// The covariance of state indices `a` and `b` (`[x, y, z, vx, vy, vz]`), when `cov` covers
    /// both and the entry is finite.
    pub fn cov_at(&self, a: usize, b: usize) -> Option<f64> {
        let i = self.cov_dims.iter().position(|&d| d == a)?;
        let j = self.cov_dims.iter().position(|&d| d == b)?;
        self.cov.get(i)?.get(j).copied().filter(|v| v.is_finite())
    }
}

/// What one scan did ([`TrackEngine::ingest`]): harrier-core's events, and the view after the
/// scan of every track the scan changed.
///
/// A scan changes every track that lives through it, not only those it updates: each is aged
/// (`age` + 1) and brought to the scan time (`t`; its estimate predicted when the time moved),
/// then updated (`updated`, `last_update`, the estimate) or coasted (`updated` false), and
/// maybe confirmed. So `changed` holds every live track after the scan — the tracks it started
/// included — and the tracks it deleted are the ones missing (each has a
/// [`Deleted`](harrier_core::tracker::TrackEvent::Deleted) event). [`ScanOutcome::apply`] turns
/// the tracks before the scan into those after it, which is what [`TrackEngine::snapshot`]
/// gives then.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanOutcome {
    /// What happened, in the order harrier-core's tracker reports it.
    pub events: Vec<harrier_core::tracker::TrackEvent>,
    /// The view after the scan of each track whose view the scan changed, in id order.
    pub changed: Vec<TrackView>,
}

impl ScanOutcome {
    /// The ids of the tracks the scan deleted.
    pub fn deleted(&self) -> impl Iterator<Item = u64> + '_ {
        self.events.iter().filter_map(|e| match e {
            harrier_core::tracker::TrackEvent::Deleted { id, .. } => Some(*id),
            _ => None,
        })
    }

    /// The live tracks after the scan, from `before`, those before it in id order (the engine's
    /// [`snapshot`](TrackEngine::snapshot), or what this function gave for the previous scan):
    /// the deleted ones removed, the changed ones replaced or added, the others kept as they
    /// were; in id order. Returns them with the events.
    pub fn apply(
        self,
        before: &[TrackView],
    ) -> (Vec<TrackView>, Vec<harrier_core::tracker::TrackEvent>) {
        let deleted: Vec<u64> = self.deleted().collect();
        let mut after = Vec::with_capacity(before.len().max(self.changed.len()));
        let mut changed = self.changed.into_iter().peekable();
        for k in before {
            while let Some(c) = changed.next_if(|c| c.id < k.id) {
                after.push(c);
            }
            if let Some(c) = changed.next_if(|c| c.id == k.id) {
                after.push(c);
            } else if !deleted.contains(&k.id) {
                after.push(k.clone());
            }
        }
        after.extend(changed);
        (after, self.events)
    }
}

/// A multi-target tracker whose track filter type is erased: the live shape of an estimator. It
/// ingests one sensor scan at a time (any kind, any platform) and says what happened as
/// [`TrackEvent`](harrier_core::tracker::TrackEvent)s with the views of the tracks that changed
/// ([`ScanOutcome`]); a snapshot gives every track at once.
pub trait TrackEngine: Send + std::fmt::Debug {
    /// Processes one scan: what happened, and the views of the tracks it changed. On error (time
    /// earlier than the last scan, a non-finite detection, a detection of the wrong size)
    /// nothing changes.
    fn ingest(&mut self, scan: &SensorScan) -> Result<ScanOutcome, EngineError>;
    /// [`ingest`](Self::ingest) of a scan from `source`: an engine with sensor registration
    /// ([`Deployment::registration`]) takes the biases out of a registered sensor's detections
    /// and updates the biases jointly with its tracks. Without registration, `ingest`.
    fn ingest_from(
        &mut self,
        scan: &SensorScan,
        _source: &ScanSource<'_>,
    ) -> Result<ScanOutcome, EngineError> {
        self.ingest(scan)
    }
    /// The registered sensors' bias estimates, in the order of
    /// [`Deployment::registration`] (empty without registration).
    fn biases(&self) -> Vec<SensorBiasView> {
        Vec::new()
    }
    /// The registered sensors' entries of an estimate line's `bias_est` (FORMAT-REGISTRATION.md
    /// §4, with the term covariance), keyed by sensor id: what `harrier replay -e tracker
    /// --register` writes (empty without registration).
    fn bias_est(&self) -> serde_json::Map<String, serde_json::Value> {
        serde_json::Map::new()
    }
    /// Every live track, tentative and confirmed, in id order: for a start, or after
    /// [`adopt`](Self::adopt); after each scan, [`ScanOutcome::apply`] keeps such a list up to
    /// date.
    fn snapshot(&self) -> Vec<TrackView>;
    /// Time of the last scan.
    fn time(&self) -> Option<f64>;
    /// The live tracks in a form any engine of the same deployment can [`adopt`](Self::adopt).
    fn handover(&self) -> Handover;
    /// Replaces this engine's tracks with `h`'s (a change of track filter or associator at run
    /// time): ids, status, hit/miss records and existence are kept, each estimate starts this
    /// engine's filter. On error nothing changes.
    fn adopt(&mut self, h: &Handover) -> Result<(), EngineError>;
    /// What the associator did so far: clusters solved, and how often a bound was hit (the
    /// bounded fallback of JIPDA and MHT).
    fn association(&self) -> harrier_core::tracker::AssociationStats;
    /// Takes scans up to `lag` seconds older than the last one, by retrodiction (harrier-core's
    /// `Tracker::set_retrodiction_lag`; 0: a scan older than the last fails). Fails for a bad
    /// lag, or a non-zero one with an associator that cannot retrodict (the multi-scan one).
    fn set_retrodiction_lag(&mut self, lag: f64) -> Result<(), EngineError>;
}

/// Tracks passed from one track engine to another: each track's record and its Gaussian estimate
/// in the engine's state layout (`dim` = 4 planar `[x, y, vx, vy]`, 6 in 3-D), covariance
/// row-major.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Handover {
    /// Time of the last scan.
    pub t: Option<f64>,
    /// State dimension of every estimate.
    pub dim: usize,
    /// Record, mean and covariance of each track.
    pub tracks: Vec<(harrier_core::tracker::Track<()>, Vec<f64>, Vec<f64>)>,
}

/// Builds the track engine of a track filter for a deployment, with an associator.
pub type TrackFilterBuildFn =
    fn(&Deployment, &Params, Association) -> Result<Box<dyn TrackEngine>, EngineError>;

/// Builds an associator's tuning for a deployment.
pub type AssociatorBuildFn = fn(&Deployment, &Params) -> Result<Association, EngineError>;

/// A named **associator** — how the live multi-target tracker associates detections with its
/// tracks (`gnn`, `jipda`, `mht`) — as a driver declares it and
/// [`crate::registry::ASSOCIATORS`] lists it. Any associator runs with any track filter.
#[derive(Debug)]
pub struct AssociatorInfo {
    /// Name.
    pub name: &'static str,
    /// One line for `harrier estimators`.
    pub summary: &'static str,
    /// Accepted parameter names with a description (and default), besides the track filters'.
    pub params: &'static [(&'static str, &'static str)],
    /// Builds its tuning.
    pub build: AssociatorBuildFn,
}

/// A named **track filter** — the filter each track of the live multi-target tracker runs (`ekf`,
/// `cdkf`, `imm`, `cimm`) — as a driver declares it and [`crate::registry::TRACK_FILTERS`] lists
/// it. It is what `[tracker] estimator` and `PUT /api/v1/estimator` choose, and not the replay
/// estimator of the same name (an [`EstimatorInfo`](super::EstimatorInfo)).
#[derive(Debug)]
pub struct TrackFilterInfo {
    /// Name.
    pub name: &'static str,
    /// One line for `harrier estimators`.
    pub summary: &'static str,
    /// Accepted parameter names with a description (and default).
    pub params: &'static [(&'static str, &'static str)],
    /// Builds the track engine that runs it.
    pub build: TrackFilterBuildFn,
}

#[cfg(test)]
mod tests {
    use harrier_core::tracker::{DeleteReason, TrackEvent};

    use super::*;

    fn view(id: u64, age: u32) -> TrackView {
        TrackView {
            id,
            status: TrackStatus::Tentative,
            t: f64::from(age),
            state: [0.0; 6],
            cov: vec![vec![1.0]],
            cov_dims: vec![0],
            updated: true,
            age,
            last_update: 0.0,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    #[test]
    fn an_outcome_removes_the_deleted_replaces_the_changed_and_keeps_the_rest() {
        let before = [view(1, 3), view(2, 3), view(4, 2), view(6, 1)];
        let outcome = ScanOutcome {
            events: vec![
                TrackEvent::Deleted {
                    id: 2,
                    reason: DeleteReason::Misses,
                },
                TrackEvent::Coasted { id: 4, misses: 1 },
                TrackEvent::Born {
                    id: 7,
                    detection: 0,
                },
            ],
            changed: vec![view(3, 1), view(4, 3), view(7, 1)],
        };
        assert_eq!(outcome.deleted().collect::<Vec<_>>(), [2]);
        let events = outcome.events.clone();
        let (after, back) = outcome.apply(&before);
        assert_eq!(back, events);
        assert_eq!(
            after,
            [view(1, 3), view(3, 1), view(4, 3), view(6, 1), view(7, 1)]
        );
        let (after, _) = ScanOutcome::default().apply(&before);
        assert_eq!(after, before);
    }
}
