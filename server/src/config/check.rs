//! [`Config::check`]: the values a TOML parser cannot check (ranges, consistency, endpoints,
//! keys), each refusal naming its key.

use harrier_core::scenario::{Motion, Road, Segment};

use super::error::ConfigError;
use super::file::Config;

impl Config {
    /// Checks the values a TOML parser cannot.
    pub fn check(&self) -> Result<(), ConfigError> {
        let bad = |m: String| Err(ConfigError::Invalid(m));
        if let Some(p) = self.clock.problem() {
            return bad(p);
        }
        self.adsb.check()?;
        self.foxglove.check()?;
        self.asterix.check()?;
        self.cot.check()?;
        self.map.check()?;
        self.registration.check()?;
        let o = self.frame.origin;
        if !(o.lat_deg.abs() <= 90.0 && o.lon_deg.abs() <= 180.0 && o.alt_m.is_finite()) {
            return bad(format!("frame.origin {o:?} is not a WGS-84 position"));
        }
        if !self.frame.plane_z.is_finite() {
            return bad("frame.plane_z must be finite".into());
        }
        let mut names = std::collections::HashSet::new();
        for tok in &self.api.tokens {
            if tok.name.is_empty() || !names.insert(tok.name.as_str()) {
                return bad(format!(
                    "api.tokens: every token needs a distinct, non-empty name, got {:?}",
                    tok.name
                ));
            }
            if tok.token.chars().count() < 16 {
                return bad(format!(
                    "api.tokens {:?}: the token must have at least 16 characters",
                    tok.name
                ));
            }
            tok.expiry().map_err(ConfigError::Invalid)?;
        }
        let t = &self.tracker;
        if !(t.reorder_window_s.is_finite() && (0.0..=60.0).contains(&t.reorder_window_s)) {
            return bad(format!(
                "tracker.reorder_window_s must be in [0, 60] s, got {}",
                t.reorder_window_s
            ));
        }
        if !(t.late_lag_s.is_finite() && (0.0..=60.0).contains(&t.late_lag_s)) {
            return bad(format!(
                "tracker.late_lag_s must be in [0, 60] s, got {}",
                t.late_lag_s
            ));
        }
        if !(t.scan_period_s.is_finite() && t.scan_period_s > 0.0) {
            return bad(format!(
                "tracker.scan_period_s must be > 0, got {}",
                t.scan_period_s
            ));
        }
        if t.queue == 0 {
            return bad("tracker.queue must be ≥ 1".into());
        }
        if let Some(p) = deployment_problem(&t.motion, &t.roads) {
            return bad(p);
        }
        if let Some(size) = t.target_size_m
            && !(size.is_finite() && size > 0.0)
        {
            return bad(format!("tracker.target_size_m must be > 0, got {size}"));
        }
        t.bound.check().map_err(ConfigError::Invalid)?;
        if self.api.ws_queue == 0 {
            return bad("api.ws_queue must be ≥ 1".into());
        }
        for (key, s) in [
            ("header_timeout_s", self.api.header_timeout_s),
            ("body_timeout_s", self.api.body_timeout_s),
        ] {
            if !(s.is_finite() && s > 0.0 && s <= 3600.0) {
                return bad(format!("api.{key} must be in (0, 3600] s, got {s}"));
            }
        }
        if self.api.max_connections == 0 {
            return bad("api.max_connections must be ≥ 1".into());
        }
        let r = &self.recorder;
        if !(1..=1000).contains(&r.flush_ms) {
            return bad(format!(
                "recorder.flush_ms must be in [1, 1000] ms, got {}",
                r.flush_ms
            ));
        }
        if r.queue == 0 {
            return bad("recorder.queue must be ≥ 1".into());
        }
        let z = &self.zenoh;
        if !(z.tracks_hz.is_finite() && z.tracks_hz > 0.0 && z.tracks_hz <= 1000.0) {
            return bad(format!(
                "zenoh.tracks_hz must be in (0, 1000], got {}",
                z.tracks_hz
            ));
        }
        if !z.tracks_key.is_empty() {
            if let Err(e) = zenoh::key_expr::KeyExpr::try_from(z.tracks_key.as_str()) {
                return bad(format!("zenoh.tracks_key {:?}: {e}", z.tracks_key));
            }
        }
        self.bus()?;
        let m = &self.mavlink;
        for e in m.gcs.iter().chain(&m.router) {
            harrier_link::frame::Endpoint::parse(e)
                .map_err(|e| ConfigError::Invalid(format!("mavlink: {e}")))?;
        }
        m.router_filters()?;
        if m.system_id == 0 {
            return bad("mavlink.system_id must be 1-255".into());
        }
        if !(m.lost_after_s.is_finite() && m.lost_after_s > 0.0) {
            return bad(format!(
                "mavlink.lost_after_s must be > 0, got {}",
                m.lost_after_s
            ));
        }
        if !(1..=60_000).contains(&m.command_timeout_ms) || m.command_attempts == 0 {
            return bad(
                "mavlink.command_timeout_ms must be in [1, 60000] and mavlink.command_attempts ≥ 1"
                    .into(),
            );
        }
        if !(m.tracks_hz.is_finite() && (0.0..=50.0).contains(&m.tracks_hz)) {
            return bad(format!(
                "mavlink.tracks_hz must be in [0, 50] (0: tracks not sent), got {}",
                m.tracks_hz
            ));
        }
        m.signing.resolve()?;
        let g = &self.guidance;
        if !(g.rate_hz.is_finite() && g.rate_hz > 0.0 && g.rate_hz <= 100.0) {
            return bad(format!(
                "guidance.rate_hz must be in (0, 100], got {}",
                g.rate_hz
            ));
        }
        let [v_min, v_max] = g.fixed_wing_speed_m_s;
        if !(v_min.is_finite() && v_max.is_finite() && v_min > 0.0 && v_min < v_max) {
            return bad(format!(
                "guidance.fixed_wing_speed_m_s must be [min, max] with 0 < min < max, got {:?}",
                g.fixed_wing_speed_m_s
            ));
        }
        if !(g.fixed_wing_bank_deg.is_finite()
            && g.fixed_wing_bank_deg > 0.0
            && g.fixed_wing_bank_deg < 90.0)
        {
            return bad(format!(
                "guidance.fixed_wing_bank_deg must be in (0, 90), got {}",
                g.fixed_wing_bank_deg
            ));
        }
        if !(g.speed_m_s.is_finite() && g.speed_m_s > 0.0) {
            return bad(format!(
                "guidance.speed_m_s must be > 0, got {}",
                g.speed_m_s
            ));
        }
        if let Some(o) = g.obstacles.iter().find(|o| {
            !(o.x_m.is_finite() && o.y_m.is_finite() && o.radius_m.is_finite() && o.radius_m > 0.0)
        }) {
            return bad(format!(
                "guidance.obstacles: {o:?} needs finite x_m, y_m and radius_m > 0"
            ));
        }
        let s = &g.safety;
        if !(s.max_distance_m.is_finite() && s.max_distance_m >= 0.0) {
            return bad(format!(
                "guidance.safety.max_distance_m must be >= 0 (0: none), got {}",
                s.max_distance_m
            ));
        }
        if !(s.floor_m.is_finite() && s.ceiling_m.is_finite() && s.floor_m < s.ceiling_m) {
            return bad(format!(
                "guidance.safety: floor_m must be below ceiling_m, got {} and {}",
                s.floor_m, s.ceiling_m
            ));
        }
        if !(s.lookahead_s.is_finite() && s.lookahead_s > 0.0) {
            return bad(format!(
                "guidance.safety.lookahead_s must be > 0, got {}",
                s.lookahead_s
            ));
        }
        if !(s.battery_floor_pct.is_finite() && (0.0..100.0).contains(&s.battery_floor_pct)) {
            return bad(format!(
                "guidance.safety.battery_floor_pct must be in [0, 100) (0: none), got {}",
                s.battery_floor_pct
            ));
        }
        if !(g.takeoff_height_m.is_finite() && g.takeoff_height_m > 0.0) {
            return bad(format!(
                "guidance.takeoff_height_m must be > 0, got {}",
                g.takeoff_height_m
            ));
        }
        Ok(())
    }
}

/// What is wrong with the motion models and roads of `[tracker]`, if anything: a negative
/// `accel_std`, a number that is not finite.
fn deployment_problem(motion: &Motion, roads: &[Road]) -> Option<String> {
    if let Some(a) = motion.accel_std
        && !(a.is_finite() && a >= 0.0)
    {
        return Some(format!("tracker.motion.accel_std must be ≥ 0, got {a}"));
    }
    let mut motion_numbers = motion
        .accel_bound
        .iter()
        .chain(motion.models.iter().filter_map(|m| m.turn_rate.as_ref()))
        .chain(motion.initial_probs.iter().flatten())
        .chain(motion.transition_matrix.iter().flatten().flatten());
    if let Some(bad) = motion_numbers.find(|v| !v.is_finite()) {
        return Some(format!("tracker.motion: {bad} is not a finite number"));
    }
    for road in roads {
        let mut numbers: Vec<f64> = road.width_m.into_iter().chain(road.sigma_m).collect();
        for segment in &road.segments {
            match segment {
                Segment::Line { start, end } => numbers.extend(start.iter().chain(end)),
                Segment::Arc {
                    center,
                    radius,
                    start,
                    end,
                    sweep_rad,
                } => {
                    numbers.extend(center.iter().chain(start).chain(end));
                    numbers.extend([*radius, *sweep_rad]);
                }
            }
        }
        if let Some(bad) = numbers.iter().find(|v| !v.is_finite()) {
            return Some(format!(
                "tracker.roads {:?}: {bad} is not a finite number",
                road.id
            ));
        }
    }
    None
}
