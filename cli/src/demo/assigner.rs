//! The demo's assigner: once every car has a settled confirmed track, the demo's UAVs are
//! assigned to the slowest one (TOGVF with phase spacing), and assigned again when the tracker
//! gives that track up, less the UAVs someone else took out of it ([`Assigner::keep`]).

/// How long the demo waits, in scan time, for a track of every car before it assigns the UAVs
/// to the slowest of the tracks there are (s).
const CAR_WAIT_S: f64 = 30.0;

/// How well a track's speed must be known (1σ, m/s) before the demo compares it with another's
/// (or [`CAR_WAIT_S`] has passed).
const SPEED_STD_M_S: f64 = 0.5;

/// A confirmed track the demo may assign the UAVs to: its ground speed and that speed's 1σ.
#[derive(Debug)]
struct Candidate {
    id: u64,
    speed: f64,
    speed_std: f64,
}

impl Candidate {
    /// The speed of `t` and its standard deviation, linearised at the estimate (infinite when
    /// the covariance has no velocity).
    fn of(t: &harrier_engine::TrackView) -> Self {
        let (vx, vy) = (t.state[3], t.state[4]);
        let speed = vx.hypot(vy);
        let var = match (t.cov_at(3, 3), t.cov_at(4, 4), t.cov_at(3, 4)) {
            (Some(xx), Some(yy), Some(xy)) if speed > 1e-6 => {
                (vx * vx * xx + 2.0 * vx * vy * xy + vy * vy * yy) / (speed * speed)
            }
            (Some(xx), Some(yy), _) => xx.max(yy),
            _ => f64::INFINITY,
        };
        Self {
            id: t.id,
            speed,
            speed_std: var.max(0.0).sqrt(),
        }
    }
}

/// What keeps the demo's UAVs assigned (see [`Assigner::keep`]).
pub(super) struct Assigner {
    pub(super) guidance: harrier_server::guidance::Guidance,
    pub(super) link: harrier_server::gcs::GcsLink,
    pub(super) snapshot:
        tokio::sync::watch::Receiver<std::sync::Arc<harrier_server::tracker::Snapshot>>,
    /// The UAVs, system ids `1..=vehicles`.
    pub(super) vehicles: u8,
    /// The cars of the world.
    pub(super) cars: usize,
    pub(super) radius: f64,
    pub(super) height: f64,
}

impl Assigner {
    /// Keeps the demo's UAVs assigned: [`Self::assign_when_ready`], then, when that assignment
    /// ends because its track was deleted (the tracker gave it up: a car lost from sight, or a
    /// ghost confirmed for a few scans), assigns them again the same way, less every UAV someone
    /// else took out of it (`overridden`: the operator wins; it is the operator's to assign
    /// again). An assignment the operator ended is left ended.
    pub(super) async fn keep(mut self) {
        let mut taken: Vec<u8> = Vec::new();
        loop {
            let Some(id) = self.assign_when_ready(&taken).await else {
                return;
            };
            let mut views = self.guidance.assignments.clone();
            loop {
                let ended = views
                    .borrow_and_update()
                    .iter()
                    .find(|a| a.id == id)
                    .map(|a| (a.ended_reason.clone(), a.vehicles.clone()));
                match ended {
                    Some((Some(reason), _))
                        if reason == harrier_server::guidance::ENDED_BY_OPERATOR =>
                    {
                        return;
                    }
                    Some((Some(reason), slots)) => {
                        taken.extend(
                            slots
                                .iter()
                                .filter(|s| {
                                    s.state == harrier_server::guidance::SlotState::Overridden
                                })
                                .map(|s| s.vehicle),
                        );
                        if taken.len() >= usize::from(self.vehicles) {
                            tracing::warn!(
                                assignment = id,
                                reason,
                                "demo: assignment ended; every UAV was taken over: none to assign"
                            );
                            return;
                        }
                        tracing::warn!(
                            assignment = id,
                            reason,
                            taken_over = ?taken,
                            "demo: assignment ended; assigning the UAVs again (not those taken over)"
                        );
                        break;
                    }
                    _ => {
                        if views.changed().await.is_err() {
                            return;
                        }
                    }
                }
            }
        }
    }

    /// Waits until every UAV is heard on the GCS link and every car has a confirmed track whose
    /// speed is known within [`SPEED_STD_M_S`] (or [`CAR_WAIT_S`] of scan time since the first:
    /// the slowest car is the one to orbit, and its track may confirm after the other's), then
    /// assigns all UAVs to the slowest confirmed track with TOGVF and phase spacing: the
    /// assignment's id, `None` once the service stops. The UAVs in `taken` are left out.
    async fn assign_when_ready(&mut self, taken: &[u8]) -> Option<u64> {
        let mut first_seen: Option<f64> = None;
        loop {
            self.snapshot.changed().await.ok()?;
            let heard = self
                .link
                .vehicles
                .borrow()
                .iter()
                .filter(|v| v.view.position.is_some() && v.status.is_some())
                .count();
            let (t, mut candidates) = {
                let s = self.snapshot.borrow();
                let candidates: Vec<Candidate> = s
                    .tracks
                    .iter()
                    .filter(|t| t.status == harrier_engine::TrackStatus::Confirmed && t.age >= 5)
                    .map(Candidate::of)
                    .collect();
                (s.t.unwrap_or(0.0), candidates)
            };
            if candidates.is_empty() || heard < usize::from(self.vehicles) {
                continue;
            }
            let waited = t - *first_seen.get_or_insert(t);
            // A speed is only compared once it is known: a young track's speed is still
            // mostly its prior (3.4 and 3.9 m/s for cars at 1.5 and 7 m/s).
            let settled = candidates.iter().all(|c| c.speed_std <= SPEED_STD_M_S);
            if (candidates.len() < self.cars || !settled) && waited < CAR_WAIT_S {
                continue;
            }
            candidates.sort_by(|a, b| a.speed.total_cmp(&b.speed));
            let track = candidates[0].id;
            let request = harrier_server::guidance::AssignmentRequest {
                vehicles: (1..=self.vehicles).filter(|v| !taken.contains(v)).collect(),
                track,
                law: "togvf".into(),
                radius_m: Some(self.radius),
                height_m: Some(self.height),
                spacing_deg: None,
                speed_m_s: None,
                orbit: None,
            };
            match self.guidance.create(request).await {
                Ok(a) => {
                    tracing::info!(
                        assignment = a.id,
                        track,
                        tracks = candidates.len(),
                        cars = self.cars,
                        candidates = ?candidates,
                        "demo: UAVs assigned to standoff-track"
                    );
                    return Some(a.id);
                }
                Err(harrier_server::guidance::AssignError::Stopped) => return None,
                Err(e) => tracing::warn!("demo: assignment refused ({e}); retrying"),
            }
        }
    }
}
