//! Tracks of cooperative targets whose reports carry their identity (ADS-B's 24-bit ICAO
//! address, AIS's MMSI): the identity is the association, so there is no gate between targets and
//! no assignment, only one Kalman filter per identity, a gate against its own outliers, and an
//! age at which a silent target is dropped.
//!
//! Each track is a 3-D constant-velocity Kalman filter (state `[x y z vx vy vz]` in a local ENU
//! frame, [`ConstantVelocity`]`<6>`, \[BLK01\] §6.3.2), predicted to each report's time
//! (eq. (5.2.3-5), (5.2.3-9)) and updated in Joseph form ([`joseph_update`],
//! eq. (5.2.3-18)) by a position report (`H = [I 0]`) or a velocity report (`H = [0 I]`). A
//! report whose NIS exceeds the gate is refused; after `max_rejects` refusals in a row the track
//! starts again from the next position (the target really is elsewhere: a new pairing of a
//! reused address, or a bad first fix). A track is started by a position; a velocity before it
//! is ignored.
//!
//! Time is the caller's (no clock here): reports of one identity must come in time order; one
//! older than its track's time by up to `late_tolerance_s` is applied at the track's time, an
//! older one is refused as late.
//!
//! # References
//! * \[BLK01\] Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, SMatrix, Vector3, Vector6};

use crate::error::EstimationError;
use crate::filter::{Kalman, Predictor as _, joseph_update};
use crate::motion::ConstantVelocity;
use crate::state::Gaussian;

/// How the tracks are filtered and aged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifiedConfig {
    /// Acceleration noise spectral density of the CV model, m²/s³.
    pub q: f64,
    /// Standard deviations of a position report (east, north, up), m.
    pub position_std: [f64; 3],
    /// Standard deviations of a velocity report (east, north, up), m/s.
    pub velocity_std: [f64; 3],
    /// Standard deviation of the unknown velocity of a new track, m/s.
    pub initial_velocity_std: f64,
    /// A report whose NIS exceeds this is refused (χ² with 3 degrees of freedom).
    pub gate_nis: f64,
    /// Refusals in a row after which the track starts again from the next position.
    pub max_rejects: u32,
    /// A track without a report for this long is dropped, s.
    pub stale_s: f64,
    /// A report older than its track by up to this much is applied at the track's time, s.
    pub late_tolerance_s: f64,
}

impl IdentifiedConfig {
    /// Checks every value (positive and finite; `late_tolerance_s` may be 0).
    pub fn validate(&self) -> Result<(), EstimationError> {
        let positive = [
            ("q", self.q),
            ("initial_velocity_std", self.initial_velocity_std),
            ("gate_nis", self.gate_nis),
            ("stale_s", self.stale_s),
        ]
        .into_iter()
        .chain(self.position_std.iter().map(|&s| ("position_std", s)))
        .chain(self.velocity_std.iter().map(|&s| ("velocity_std", s)));
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(EstimationError::InvalidParameter(format!(
                    "{name} must be positive and finite, got {v}"
                )));
            }
        }
        if !(self.late_tolerance_s.is_finite() && self.late_tolerance_s >= 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "late_tolerance_s must be ≥ 0, got {}",
                self.late_tolerance_s
            )));
        }
        Ok(())
    }
}

/// One report of a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Report {
    /// Its position in the local frame, m.
    Position(Vector3<f64>),
    /// Its velocity in the local frame, m/s.
    Velocity(Vector3<f64>),
}

/// What a report did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// A position started a track.
    Started,
    /// The track was updated.
    Updated,
    /// Refused by the gate (an outlier of the track).
    Gated,
    /// Older than the track by more than the tolerance.
    Late,
    /// A velocity of a target without a track (nothing to update).
    NoTrack,
    /// The update failed numerically (non-finite or not positive definite): the track was
    /// dropped and starts again from the next position.
    Reset,
}

/// The track of one identity.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifiedTrack {
    /// The estimate at `t`.
    pub state: Gaussian<6>,
    /// The estimate's time (its last report's), s.
    pub t: f64,
    /// Reports that updated or started it.
    pub updates: u64,
    /// A velocity report has updated it (else its velocity comes from positions only).
    pub velocity_reported: bool,
    rejects: u32,
}

/// The tracks of every identity, keyed by `K`.
#[derive(Debug, Clone)]
pub struct IdentifiedTracks<K> {
    config: IdentifiedConfig,
    tracks: BTreeMap<K, IdentifiedTrack>,
}

impl<K: Ord + Copy> IdentifiedTracks<K> {
    /// No tracks yet; `config` is checked.
    pub fn new(config: IdentifiedConfig) -> Result<Self, EstimationError> {
        config.validate()?;
        Ok(Self {
            config,
            tracks: BTreeMap::new(),
        })
    }

    /// Applies a report of `id` made at `t` (s, the caller's time line).
    pub fn report(&mut self, id: K, t: f64, report: Report) -> Outcome {
        let c = self.config;
        let Some(track) = self.tracks.get_mut(&id) else {
            return match report {
                Report::Position(p) => {
                    self.tracks.insert(id, start(&c, p, t));
                    Outcome::Started
                }
                Report::Velocity(_) => Outcome::NoTrack,
            };
        };
        if t < track.t - c.late_tolerance_s {
            return Outcome::Late;
        }
        let t = t.max(track.t);
        match step(&c, track, t, report) {
            Ok(Some(state)) => {
                track.state = state;
                track.t = t;
                track.updates += 1;
                track.rejects = 0;
                track.velocity_reported |= matches!(report, Report::Velocity(_));
                Outcome::Updated
            }
            Ok(None) => {
                track.rejects += 1;
                if track.rejects >= c.max_rejects {
                    self.tracks.remove(&id);
                }
                Outcome::Gated
            }
            Err(_) => {
                self.tracks.remove(&id);
                Outcome::Reset
            }
        }
    }

    /// Drops the tracks without a report since `now − stale_s`; returns how many.
    pub fn age_out(&mut self, now: f64) -> usize {
        let before = self.tracks.len();
        let stale = self.config.stale_s;
        self.tracks.retain(|_, tr| now - tr.t <= stale);
        before - self.tracks.len()
    }

    /// The tracks, by identity.
    pub fn iter(&self) -> impl Iterator<Item = (&K, &IdentifiedTrack)> {
        self.tracks.iter()
    }

    /// The track of `id`.
    pub fn get(&self, id: &K) -> Option<&IdentifiedTrack> {
        self.tracks.get(id)
    }

    /// How many tracks there are.
    pub fn len(&self) -> usize {
        self.tracks.len()
    }

    /// No track.
    pub fn is_empty(&self) -> bool {
        self.tracks.is_empty()
    }
}

/// A new track at `p` with an unknown velocity.
fn start(c: &IdentifiedConfig, p: Vector3<f64>, t: f64) -> IdentifiedTrack {
    let mut cov = SMatrix::<f64, 6, 6>::zeros();
    for i in 0..3 {
        cov[(i, i)] = c.position_std[i].powi(2);
        cov[(i + 3, i + 3)] = c.initial_velocity_std.powi(2);
    }
    IdentifiedTrack {
        state: Gaussian {
            mean: Vector6::new(p.x, p.y, p.z, 0.0, 0.0, 0.0),
            cov,
        },
        t,
        updates: 1,
        velocity_reported: false,
        rejects: 0,
    }
}

/// Predicts `track` to `t` (\[BLK01\] eq. (5.2.3-5), (5.2.3-9)) and updates it with `report`
/// in Joseph form (eq. (5.2.3-18)); `None` when its NIS `νᵀ S⁻¹ ν` exceeds the gate.
fn step(
    c: &IdentifiedConfig,
    track: &IdentifiedTrack,
    t: f64,
    report: Report,
) -> Result<Option<Gaussian<6>>, EstimationError> {
    let predicted = Kalman.predict(&ConstantVelocity::<6>::new(c.q), &track.state, t - track.t)?;
    let (z, offset, std) = match report {
        Report::Position(p) => (p, 0, c.position_std),
        Report::Velocity(v) => (v, 3, c.velocity_std),
    };
    if !z.iter().all(|v| v.is_finite()) {
        return Err(EstimationError::NonFinite("report"));
    }
    let mut h = SMatrix::<f64, 3, 6>::zeros();
    h.fixed_view_mut::<3, 3>(0, offset)
        .copy_from(&Matrix3::identity());
    let r = Matrix3::from_diagonal(&Vector3::from(std).map(|s| s * s));
    let innovation = z - h * predicted.mean;
    let posterior = joseph_update(&predicted, innovation, &h, &r)?;
    let nis = posterior.nis()?;
    if nis > c.gate_nis {
        return Ok(None);
    }
    Ok(Some(posterior.state))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> IdentifiedConfig {
        IdentifiedConfig {
            q: 1.0,
            position_std: [10.0, 10.0, 10.0],
            velocity_std: [1.0, 1.0, 1.0],
            initial_velocity_std: 300.0,
            gate_nis: 30.0,
            max_rejects: 3,
            stale_s: 60.0,
            late_tolerance_s: 1.0,
        }
    }

    #[test]
    fn a_straight_flight_is_followed_from_positions_and_velocities() {
        let mut tracks = IdentifiedTracks::new(config()).unwrap();
        let v = Vector3::new(200.0, -100.0, 5.0);
        let p0 = Vector3::new(-20_000.0, 30_000.0, 9_000.0);
        assert_eq!(
            tracks.report(7_u32, 0.0, Report::Position(p0)),
            Outcome::Started
        );
        assert_eq!(tracks.report(7, 0.2, Report::Velocity(v)), Outcome::Updated);
        for k in 1..=40 {
            let t = f64::from(k) * 0.5;
            let r = if k % 2 == 0 {
                Report::Position(p0 + v * t)
            } else {
                Report::Velocity(v)
            };
            assert_eq!(tracks.report(7, t, r), Outcome::Updated, "{k}");
        }
        let tr = tracks.get(&7).unwrap();
        assert_eq!(tr.t, 20.0);
        let pos = tr.state.mean.fixed_rows::<3>(0).into_owned();
        assert!((pos - (p0 + v * 20.0)).norm() < 1.0, "{pos}");
        assert!(tr.velocity_reported);
        assert_eq!(tr.updates, 42);
    }

    #[test]
    fn outliers_are_gated_then_the_track_starts_again() {
        let mut tracks = IdentifiedTracks::new(config()).unwrap();
        let p = Vector3::new(0.0, 0.0, 1000.0);
        tracks.report(1_u32, 0.0, Report::Position(p));
        assert_eq!(tracks.report(1, 1.0, Report::Position(p)), Outcome::Updated);
        let far = Vector3::new(50_000.0, 0.0, 1000.0);
        for _ in 0..2 {
            assert_eq!(tracks.report(1, 2.0, Report::Position(far)), Outcome::Gated);
            assert!(tracks.get(&1).is_some());
        }
        assert_eq!(tracks.report(1, 2.0, Report::Position(far)), Outcome::Gated);
        assert!(tracks.get(&1).is_none());
        assert_eq!(
            tracks.report(1, 3.0, Report::Position(far)),
            Outcome::Started
        );
    }

    #[test]
    fn late_stale_and_trackless_reports() {
        let mut tracks = IdentifiedTracks::new(config()).unwrap();
        let p = Vector3::new(0.0, 0.0, 0.0);
        assert_eq!(
            tracks.report(2_u32, 0.0, Report::Velocity(Vector3::zeros())),
            Outcome::NoTrack
        );
        tracks.report(2, 10.0, Report::Position(p));
        // Within the tolerance: applied at the track's time.
        assert_eq!(tracks.report(2, 9.5, Report::Position(p)), Outcome::Updated);
        assert_eq!(tracks.get(&2).unwrap().t, 10.0);
        assert_eq!(tracks.report(2, 8.0, Report::Position(p)), Outcome::Late);
        let nan = Report::Position(Vector3::new(f64::NAN, 0.0, 0.0));
        assert_eq!(tracks.report(2, 11.0, nan), Outcome::Reset);
        assert!(tracks.is_empty());
        tracks.report(3, 0.0, Report::Position(p));
        tracks.report(4, 50.0, Report::Position(p));
        assert_eq!(tracks.age_out(70.0), 1);
        assert_eq!(tracks.len(), 1);
        assert!(tracks.get(&4).is_some());
    }

    #[test]
    fn a_bad_configuration_is_refused() {
        let mut c = config();
        c.position_std[1] = 0.0;
        assert!(IdentifiedTracks::<u32>::new(c).is_err());
        let mut c = config();
        c.stale_s = f64::NAN;
        assert!(IdentifiedTracks::<u32>::new(c).is_err());
    }
}
