//! An assignment as the API sees it: the request ([`AssignmentRequest`]), checked against the
//! flight envelope into a [`Plan`], and its view ([`AssignmentView`], one [`SlotView`] per
//! vehicle). Pure: no actor, no I/O.

use harrier_core::guidance::Orbit;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::GuidanceSettings;

/// A new assignment, as `POST /api/v1/assignments` takes it.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AssignmentRequest {
    /// MAVLink system ids of the vehicles (1–255, each in no other active assignment).
    #[schema(min_items = 1, max_items = 16)]
    pub vehicles: Vec<u8>,
    /// The track to follow (a live track id).
    pub track: u64,
    /// `togvf`, `lgvf` or `formation`.
    pub law: String,
    /// Standoff radius R (m).
    #[serde(default)]
    pub radius_m: Option<f64>,
    /// Observation height H above the target (m).
    #[serde(default)]
    pub height_m: Option<f64>,
    /// Phase spacing between neighbours on the circle (degrees); default 360/n.
    #[serde(default)]
    pub spacing_deg: Option<f64>,
    /// Nominal speed relative to the target (m/s); default `guidance.speed_m_s`.
    #[serde(default)]
    pub speed_m_s: Option<f64>,
    /// `ccw` or `cw` (default `ccw`).
    #[serde(default)]
    pub orbit: Option<String>,
}

/// Default standoff radius (m).
pub const DEFAULT_RADIUS_M: f64 = 60.0;
/// Default observation height (m).
pub const DEFAULT_HEIGHT_M: f64 = 40.0;

/// An assignment's checked geometry: what [`AssignmentRequest::plan`] makes of a request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    /// Standoff radius (m).
    pub radius: f64,
    /// Observation height (m).
    pub height: f64,
    /// Phase spacing (rad).
    pub spacing: f64,
    /// Speed relative to the target (m/s).
    pub speed: f64,
    /// Direction of the orbit.
    pub orbit: Orbit,
}

impl AssignmentRequest {
    /// Checks the request against the flight envelope and fills in the defaults: every value
    /// finite and in range, or an error naming the field. (Whether the vehicles and the track
    /// exist is the guidance loop's to say.)
    pub fn plan(&self, settings: &GuidanceSettings) -> Result<Plan, String> {
        let bad = |m: String| Err(m);
        if self.vehicles.is_empty() || self.vehicles.len() > 16 {
            return bad("vehicles: give 1 to 16 system ids".into());
        }
        let mut ids = self.vehicles.clone();
        ids.sort_unstable();
        ids.dedup();
        if ids.len() != self.vehicles.len() || ids.contains(&0) {
            return bad("vehicles: ids must be 1-255 and distinct".into());
        }
        if !matches!(self.law.as_str(), "togvf" | "lgvf" | "formation") {
            return bad(format!(
                "law {:?}: expected togvf, lgvf or formation",
                self.law
            ));
        }
        let radius = self.radius_m.unwrap_or(DEFAULT_RADIUS_M);
        let height = self.height_m.unwrap_or(DEFAULT_HEIGHT_M);
        let speed = self.speed_m_s.unwrap_or(settings.speed);
        let n = self.vehicles.len();
        let spacing = self.spacing_deg.unwrap_or(360.0 / n as f64).to_radians();
        let limits = settings.limits;
        if !(radius.is_finite() && radius > 0.0 && radius <= 10_000.0) {
            return bad(format!("radius_m must be in (0, 10000], got {radius}"));
        }
        let r_min = limits.min_turn_radius(speed);
        if radius < r_min {
            return bad(format!(
                "radius_m {radius} is below the vehicles' turning radius {r_min:.1} m at {speed} m/s"
            ));
        }
        if !(height.is_finite() && height > 0.0 && height <= 5_000.0) {
            return bad(format!("height_m must be in (0, 5000], got {height}"));
        }
        if !(speed.is_finite() && speed > 0.0 && speed <= limits.v_max) {
            return bad(format!(
                "speed_m_s must be in (0, {}], got {speed}",
                limits.v_max
            ));
        }
        if !(spacing.is_finite()
            && spacing > 0.0
            && spacing * n as f64 <= std::f64::consts::TAU + 1e-9)
        {
            return bad(format!(
                "spacing_deg must be > 0 with n × spacing ≤ 360, got {}",
                spacing.to_degrees()
            ));
        }
        let orbit = match self.orbit.as_deref() {
            None | Some("ccw") => Orbit::Ccw,
            Some("cw") => Orbit::Cw,
            Some(o) => return bad(format!("orbit {o:?}: expected ccw or cw")),
        };
        Ok(Plan {
            radius,
            height,
            spacing,
            speed,
            orbit,
        })
    }
}

/// Where one vehicle of an assignment is.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct SlotView {
    /// The vehicle.
    pub vehicle: u8,
    /// `waiting` (no telemetry yet), `arming`, `taking_off`, `offboard`, `lost`, `failed`, `hold`
    /// (the assignment ended).
    pub state: String,
    /// Why it failed, when it did.
    pub error: Option<String>,
    /// Horizontal distance to the track estimate minus R (m).
    pub range_error_m: Option<f64>,
    /// Phase around the track estimate (degrees, from east, counter-clockwise).
    pub phase_deg: Option<f64>,
    /// The last commanded velocity (ENU, m/s).
    pub commanded_velocity: Option<[f64; 3]>,
}

/// An assignment as the API shows it.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct AssignmentView {
    /// Assignment id.
    pub id: u64,
    /// The track.
    pub track: u64,
    /// The law.
    pub law: String,
    /// R (m).
    pub radius_m: f64,
    /// H (m).
    pub height_m: f64,
    /// Phase spacing (degrees).
    pub spacing_deg: f64,
    /// Speed relative to the target (m/s).
    pub speed_m_s: f64,
    /// `ccw` or `cw`.
    pub orbit: String,
    /// `active` or `ended`.
    pub state: String,
    /// Why it ended.
    pub ended_reason: Option<String>,
    /// When it was created (UNIX s).
    pub created_unix: f64,
    /// Its vehicles.
    pub vehicles: Vec<SlotView>,
}
