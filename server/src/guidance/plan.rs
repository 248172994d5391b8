//! An assignment as the API sees it: the request ([`AssignmentRequest`]), checked against the
//! flight envelope into a [`Plan`], and its view ([`AssignmentView`], one [`SlotView`] per
//! vehicle), with the fixed sets of values they carry as enums ([`Law`], [`OrbitDirection`],
//! [`AssignmentState`], [`SlotState`]: OpenAPI components, each variant sent as its snake-case
//! name). Pure: no actor, no I/O.

use harrier_core::guidance::Orbit;
use harrier_link::autopilot::{Autopilot, Frame, Personality};
use harrier_link::geo::LocalFrame;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use harrier_core::guidance::Limits;
use harrier_core::guidance::obstacle::Obstacle;

/// A new assignment, as `POST /api/v1/assignments` takes it.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AssignmentRequest {
    /// MAVLink system ids of the vehicles (1–255, each in no other active assignment).
    #[schema(min_items = 1, max_items = 16)]
    pub vehicles: Vec<u8>,
    /// The track to follow (a live track id).
    pub track: u64,
    /// `togvf`, `lgvf`, `formation`, or a hand-off: `handoff_orbit`, `handoff_follow`,
    /// `handoff_camera` (the `Law` schema; another name is refused with 422).
    #[schema(value_type = Law)]
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
    /// `ccw` or `cw` (default `ccw`; the `OrbitDirection` schema; another value is refused with
    /// 422).
    #[serde(default)]
    #[schema(value_type = Option<OrbitDirection>)]
    pub orbit: Option<String>,
}

/// The guidance law of an assignment (GUIDANCE.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Law {
    /// Time-optimal guidance vector field standoff (\[CIMM\] §4.1–4.2), with phase
    /// coordination when several vehicles share the track.
    Togvf,
    /// Lyapunov guidance vector field standoff (the baseline), with phase coordination.
    Lgvf,
    /// The \[BOT\] formation: the track leads, the vehicles hold the line-of-sight ranges of a
    /// shape around it, steered around the obstacles.
    Formation,
    /// Hand-off: the autopilot orbits the predicted track itself (PX4's MAV_CMD_DO_ORBIT,
    /// ArduPlane's guided loiter at R), re-centred twice a second. ArduCopter has no orbit
    /// command (refused).
    HandoffOrbit,
    /// Hand-off: the autopilot follows the track from FOLLOW_TARGET messages (position, velocity,
    /// covariance) at 10 Hz in its follow mode (PX4 AUTO.FOLLOW_TARGET, ArduCopter FOLLOW; a fixed
    /// wing is refused).
    HandoffFollow,
    /// Hand-off: the vehicle's camera is pointed at the track (MAV_CMD_DO_SET_ROI_LOCATION, to
    /// its gimbal manager when it announces one) at every update of the track; the vehicle
    /// flies on as it was.
    HandoffCamera,
}

impl Law {
    /// Every law.
    pub const ALL: [Self; 6] = [
        Self::Togvf,
        Self::Lgvf,
        Self::Formation,
        Self::HandoffOrbit,
        Self::HandoffFollow,
        Self::HandoffCamera,
    ];

    /// The name on the wire (`togvf`, `lgvf`, `formation`, `handoff_orbit`, `handoff_follow`,
    /// `handoff_camera`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Togvf => "togvf",
            Self::Lgvf => "lgvf",
            Self::Formation => "formation",
            Self::HandoffOrbit => "handoff_orbit",
            Self::HandoffFollow => "handoff_follow",
            Self::HandoffCamera => "handoff_camera",
        }
    }

    /// Whether the target is handed to the autopilot rather than flown by the guidance.
    pub fn is_handoff(self) -> bool {
        matches!(
            self,
            Self::HandoffOrbit | Self::HandoffFollow | Self::HandoffCamera
        )
    }

    /// The law named `name`, if any.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|l| l.as_str() == name)
    }
}

/// The direction of a standoff orbit, seen from above.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum OrbitDirection {
    /// Counter-clockwise (the default).
    Ccw,
    /// Clockwise.
    Cw,
}

impl OrbitDirection {
    /// `ccw` or `cw`, if `name` is one of them.
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "ccw" => Some(Self::Ccw),
            "cw" => Some(Self::Cw),
            _ => None,
        }
    }
}

/// The laws' sense of rotation.
impl From<OrbitDirection> for Orbit {
    fn from(o: OrbitDirection) -> Self {
        match o {
            OrbitDirection::Ccw => Self::Ccw,
            OrbitDirection::Cw => Self::Cw,
        }
    }
}

/// Where an assignment is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum AssignmentState {
    /// Its vehicles fly it.
    Active,
    /// Ended (by the operator, or its track was deleted: `ended_reason`); its vehicles were sent
    /// to Hold.
    Ended,
}

/// The `ended_reason` of an assignment the operator ended (through the API); any other reason
/// is the service's (its track was deleted).
pub const ENDED_BY_OPERATOR: &str = "ended by the operator";

/// Where one vehicle of an assignment is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SlotState {
    /// No usable telemetry yet (not connected, or no position and velocity).
    Waiting,
    /// Its offboard sequence is arming it.
    Arming,
    /// Its offboard sequence is taking it off (ArduPilot: until it is up).
    TakingOff,
    /// Under the ground station's control, flying the law's commands: PX4's OFFBOARD, ArduPilot's
    /// GUIDED.
    Offboard,
    /// The target is handed to its autopilot: it orbits it, follows it or points its camera at
    /// it itself, from the messages the guidance sends (a hand-off law).
    HandedOff,
    /// Its link is lost: paused, it flies the assignment again when it speaks again.
    Lost,
    /// Its offboard sequence failed (a refused or unacknowledged command), or the safety envelope
    /// took it out (found outside the geofence: sent to Hold; battery below the floor: sent home);
    /// `error` says which. Out of the assignment until the operator resumes it.
    Failed,
    /// Someone else took it (`overridden` says who and what): its mode or arming changed by no
    /// command of Harrier's (a router client, the RC switch, the autopilot's failsafe, a landing,
    /// a disarm), or the operator commanded it through the API. Out of the assignment: Harrier
    /// sends it nothing until the operator resumes it
    /// (`POST /api/v1/assignments/{id}/vehicles/{vehicle}/resume`).
    Overridden,
    /// The assignment ended: sent to Hold.
    Hold,
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
    /// Phase spacing (rad); `None`: 360° over the vehicles flying the ring.
    pub spacing: Option<f64>,
    /// Speed relative to the target (m/s).
    pub speed: f64,
    /// Direction of the orbit.
    pub orbit: OrbitDirection,
    /// The law.
    pub law: Law,
}

impl AssignmentRequest {
    /// Checks the request against its vehicles' personalities (`personalities`: the flight
    /// envelopes of their airframes, a multirotor's when empty, and what their autopilots can be
    /// handed) and fills in the defaults: every value finite and in range, or an error naming the
    /// field. (Whether the vehicles and the track exist is the guidance loop's to say.)
    pub fn plan(
        &self,
        settings: &GuidanceSettings,
        personalities: &[Personality],
    ) -> Result<Plan, String> {
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
        let Some(law) = Law::parse(&self.law) else {
            return bad(format!(
                "law {:?}: expected togvf, lgvf, formation, handoff_orbit, handoff_follow or \
                 handoff_camera",
                self.law
            ));
        };
        for p in personalities {
            let refused = match law {
                Law::HandoffOrbit
                    if p.autopilot == Autopilot::ArduPilot && p.frame == Frame::Multirotor =>
                {
                    Some("ArduCopter 4.x has no orbit command (DO_ORBIT is not in its GUIDED)")
                }
                Law::HandoffFollow if p.follow().is_none() => {
                    Some("a fixed wing has no follow mode")
                }
                _ => None,
            };
            if let Some(why) = refused {
                return bad(format!("law {}: {why} ({})", law.as_str(), p.label()));
            }
        }
        let frames: Vec<Frame> = personalities.iter().map(|p| p.frame).collect();
        let radius = self.radius_m.unwrap_or(DEFAULT_RADIUS_M);
        let height = self.height_m.unwrap_or(DEFAULT_HEIGHT_M);
        let speed = self.speed_m_s.unwrap_or(settings.speed);
        let n = self.vehicles.len();
        let spacing = self.spacing_deg.unwrap_or(360.0 / n as f64).to_radians();
        let given = self.spacing_deg.is_some();
        let envelopes: Vec<&Limits> = if frames.is_empty() {
            vec![&settings.multirotor]
        } else {
            frames.iter().map(|f| settings.limits(*f)).collect()
        };
        let v_max = envelopes
            .iter()
            .map(|l| l.v_max)
            .fold(f64::INFINITY, f64::min);
        let v_min = envelopes.iter().map(|l| l.v_min).fold(0.0, f64::max);
        if !(radius.is_finite() && radius > 0.0 && radius <= 10_000.0) {
            return bad(format!("radius_m must be in (0, 10000], got {radius}"));
        }
        let r_min = envelopes
            .iter()
            .map(|l| l.min_turn_radius(speed.max(l.v_min)))
            .fold(0.0, f64::max);
        if radius < r_min {
            return bad(format!(
                "radius_m {radius} is below the vehicles' turning radius {r_min:.1} m at {speed} m/s"
            ));
        }
        if !(height.is_finite() && height > 0.0 && height <= 5_000.0) {
            return bad(format!("height_m must be in (0, 5000], got {height}"));
        }
        if !(speed.is_finite() && speed > 0.0 && speed <= v_max) {
            return bad(format!("speed_m_s must be in (0, {v_max}], got {speed}"));
        }
        if speed < v_min {
            return bad(format!(
                "speed_m_s {speed} is below the fixed wings' minimum airspeed {v_min} m/s"
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
            None => OrbitDirection::Ccw,
            Some(o) => OrbitDirection::parse(o)
                .ok_or_else(|| format!("orbit {o:?}: expected ccw or cw"))?,
        };
        Ok(Plan {
            radius,
            height,
            spacing: given.then_some(spacing),
            speed,
            orbit,
            law,
        })
    }
}

impl Plan {
    /// The phase spacing (rad) of a ring of `n` vehicles: the request's, else 360° / n.
    pub fn spacing_of(&self, n: usize) -> f64 {
        self.spacing
            .unwrap_or(std::f64::consts::TAU / n.max(1) as f64)
    }
}

/// Who took a vehicle out of its slot, and what was seen (a [`SlotState::Overridden`] slot).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct OverrideView {
    /// The mode it was in before (its autopilot's name), when known.
    pub from_mode: Option<String>,
    /// The mode it was seen in after (its autopilot's name), when known.
    pub to_mode: Option<String>,
    /// Whether it was disarmed.
    pub disarmed: bool,
    /// Who: `api` (an operator's command through the API), `router_client` (a command from a
    /// client of the MAVLink router shortly before), `vehicle` (no command anyone sent through
    /// Harrier: the RC switch, the autopilot's failsafe, its own landing).
    pub by: OverrideSource,
    /// What was seen, in words (the command and the client's address, when known).
    pub detail: String,
    /// When (UNIX s).
    pub time_unix: f64,
}

/// Who took a vehicle out of its slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum OverrideSource {
    /// An operator's command through Harrier's API.
    Api,
    /// A router client's command (QGroundControl, MAVProxy, MAVSDK through Harrier's router).
    RouterClient,
    /// The vehicle itself, as far as Harrier knows: the RC switch, a failsafe, a landing.
    Vehicle,
}

impl OverrideSource {
    /// Every source, in declaration order.
    pub const ALL: [Self; 3] = [Self::Api, Self::RouterClient, Self::Vehicle];

    /// The name on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Api => "api",
            Self::RouterClient => "router_client",
            Self::Vehicle => "vehicle",
        }
    }
}

/// Where one vehicle of an assignment is.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct SlotView {
    /// The vehicle.
    pub vehicle: u8,
    /// `waiting` (no telemetry yet; a hand-off: on the ground; a vehicle back from a new
    /// address until the operator accepts it), `arming`, `taking_off`, `offboard` (PX4
    /// OFFBOARD or ArduPilot GUIDED), `handed_off`, `lost`, `failed`, `overridden` (someone
    /// else took it), `hold` (the assignment ended).
    pub state: SlotState,
    /// Why it failed, or why it waits, when it does.
    pub error: Option<String>,
    /// Who took it and what was seen, while `overridden`.
    pub overridden: Option<OverrideView>,
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
    pub law: Law,
    /// R (m).
    pub radius_m: f64,
    /// H (m).
    pub height_m: f64,
    /// Phase spacing (degrees).
    pub spacing_deg: f64,
    /// Speed relative to the target (m/s).
    pub speed_m_s: f64,
    /// `ccw` or `cw`.
    pub orbit: OrbitDirection,
    /// `active` or `ended`.
    pub state: AssignmentState,
    /// Why it ended.
    pub ended_reason: Option<String>,
    /// When it was created (UNIX s).
    pub created_unix: f64,
    /// Its vehicles.
    pub vehicles: Vec<SlotView>,
}

/// Settings of the loop.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidanceSettings {
    /// Setpoint rate (Hz).
    pub rate_hz: f64,
    /// Flight envelope of a multirotor.
    pub multirotor: Limits,
    /// Flight envelope of a fixed wing (`guidance.fixed_wing_*`).
    pub fixed_wing: Limits,
    /// Default speed (m/s).
    pub speed: f64,
    /// Takeoff height above home (m).
    pub takeoff_height: f64,
    /// Obstacles the `formation` law steers around (ENU).
    pub obstacles: Vec<Obstacle>,
    /// The safety envelope on every setpoint.
    pub envelope: super::envelope::Envelope,
    /// The server's ENU frame (a hand-off's points go out in WGS-84).
    pub frame: LocalFrame,
}

impl GuidanceSettings {
    /// The flight envelope of an airframe.
    pub fn limits(&self, frame: Frame) -> &Limits {
        match frame {
            Frame::Multirotor => &self.multirotor,
            Frame::FixedWing => &self.fixed_wing,
        }
    }
}

/// The guidance reads its own section of the configuration (`[guidance]`, `[frame]`).
impl From<&crate::config::Config> for GuidanceSettings {
    /// The guidance loop's settings (`[guidance]`): the multirotor envelope, the fixed wing's from
    /// its airspeed band and bank limit (climbing 5 m/s), the obstacles as discs, and the
    /// server's frame.
    fn from(c: &crate::config::Config) -> Self {
        use harrier_core::guidance::{Limits, obstacle::Obstacle};
        let g = &c.guidance;
        let [v_min, v_max] = g.fixed_wing_speed_m_s;
        let obstacles: Vec<Obstacle> = g
            .obstacles
            .iter()
            .map(|o| Obstacle {
                center: nalgebra::Vector2::new(o.x_m, o.y_m),
                radius: o.radius_m,
            })
            .collect();
        let s = &g.safety;
        let envelope = super::envelope::Envelope {
            no_fly: if s.no_fly {
                obstacles.clone()
            } else {
                Vec::new()
            },
            max_distance_m: (s.max_distance_m > 0.0).then_some(s.max_distance_m),
            floor_m: Some(s.floor_m),
            ceiling_m: Some(s.ceiling_m),
            lookahead_s: s.lookahead_s,
            battery_floor_pct: (s.battery_floor_pct > 0.0).then_some(s.battery_floor_pct),
        };
        Self {
            rate_hz: g.rate_hz,
            multirotor: Limits::multirotor(),
            fixed_wing: Limits::bank_limited(v_min, v_max, g.fixed_wing_bank_deg.to_radians(), 5.0),
            speed: g.speed_m_s,
            takeoff_height: g.takeoff_height_m,
            obstacles,
            envelope,
            frame: harrier_link::geo::LocalFrame::new(c.frame.origin),
        }
    }
}

#[cfg(test)]
mod tests {
    use serde::Serialize;
    use serde_json::json;

    use super::*;

    fn names<T: Serialize>(values: &[T]) -> serde_json::Value {
        serde_json::to_value(values).expect("names")
    }

    /// A fixed wing narrows the envelope: its minimum airspeed and its bank-limited turning
    /// radius.
    #[test]
    fn a_fixed_wing_in_the_assignment_bounds_speed_and_radius() {
        let settings = GuidanceSettings {
            rate_hz: 20.0,
            multirotor: Limits::multirotor(),
            fixed_wing: Limits::bank_limited(10.0, 20.0, 45f64.to_radians(), 5.0),
            speed: 5.0,
            takeoff_height: 30.0,
            obstacles: Vec::new(),
            envelope: super::super::envelope::Envelope::default(),
            frame: LocalFrame::new(harrier_link::geo::Geodetic::new(47.0, 8.0, 400.0)),
        };
        let req = |speed: Option<f64>, radius: f64| AssignmentRequest {
            vehicles: vec![1, 2],
            track: 1,
            law: "togvf".into(),
            radius_m: Some(radius),
            height_m: None,
            spacing_deg: None,
            speed_m_s: speed,
            orbit: None,
        };
        let p = |l: &str| Personality::from_label(l).expect("label");
        let mixed = [p("px4-mc"), p("ardupilot-fw")];
        assert!(req(None, 150.0).plan(&settings, &[p("px4-mc"); 2]).is_ok());
        let e = req(None, 150.0).plan(&settings, &mixed).expect_err("5 m/s");
        assert!(e.contains("minimum airspeed 10"), "{e}");
        assert!(req(Some(12.5), 150.0).plan(&settings, &mixed).is_ok());
        // 16 m/s at 45°: a radius of 26 m.
        let e = req(Some(16.0), 20.0)
            .plan(&settings, &mixed)
            .expect_err("too tight");
        assert!(e.contains("turning radius 26.1"), "{e}");
        let e = req(Some(18.0), 150.0)
            .plan(&settings, &mixed)
            .expect_err("above 15");
        assert!(e.contains("(0, 15]"), "{e}");
        // What an autopilot cannot be handed.
        let handoff = |law: &str, who: &[Personality]| {
            AssignmentRequest {
                law: law.into(),
                ..req(Some(12.0), 150.0)
            }
            .plan(&settings, who)
        };
        let e = handoff("handoff_orbit", &[p("ardupilot-mc")]).expect_err("no Copter orbit");
        assert!(e.contains("ArduCopter 4.x has no orbit command"), "{e}");
        let e = handoff("handoff_follow", &[p("px4-fw")]).expect_err("no FW follow");
        assert!(e.contains("no follow mode"), "{e}");
        assert!(handoff("handoff_orbit", &[p("px4-mc"), p("ardupilot-fw")]).is_ok());
        assert!(handoff("handoff_camera", &mixed).is_ok());
    }

    /// The names the page (`web/`) and the Python clients read.
    #[test]
    fn the_states_and_laws_are_sent_by_their_former_names() {
        use SlotState as S;
        let slots = [
            S::Waiting,
            S::Arming,
            S::TakingOff,
            S::Offboard,
            S::HandedOff,
            S::Lost,
            S::Failed,
            S::Hold,
        ];
        assert_eq!(
            names(&slots),
            json!([
                "waiting",
                "arming",
                "taking_off",
                "offboard",
                "handed_off",
                "lost",
                "failed",
                "hold"
            ])
        );
        let states = [AssignmentState::Active, AssignmentState::Ended];
        assert_eq!(names(&states), json!(["active", "ended"]));
        assert_eq!(
            names(&Law::ALL),
            json!([
                "togvf",
                "lgvf",
                "formation",
                "handoff_orbit",
                "handoff_follow",
                "handoff_camera"
            ])
        );
        for law in Law::ALL {
            assert_eq!(Law::parse(law.as_str()), Some(law));
            assert_eq!(json!(law.as_str()), json!(law));
        }
        assert_eq!(Law::parse("spiral"), None);
        let orbits = [OrbitDirection::Ccw, OrbitDirection::Cw];
        assert_eq!(names(&orbits), json!(["ccw", "cw"]));
        for o in orbits {
            assert_eq!(json!(o).as_str().and_then(OrbitDirection::parse), Some(o));
        }
    }
}
