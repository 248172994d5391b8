//! Reading a [`SimScenario`] from JSON: serde checks of single numbers (with the line and column
//! serde_json reports), then [`SimScenario::validate`] for what the types cannot say.

use std::path::Path;

use super::check::{ScenarioError, Source};
use super::{Behaviour, BiasModel, Pointing, SensorType, SimScenario, TargetMotion};

impl SimScenario {
    /// A preset by name, a JSON file otherwise.
    pub fn load(name_or_path: &str) -> Result<Self, ScenarioError> {
        if let Some(s) = Self::preset(name_or_path) {
            return Ok(s);
        }
        let text = std::fs::read_to_string(name_or_path).map_err(|e| ScenarioError::NotFound {
            name: name_or_path.to_owned(),
            message: e.to_string(),
        })?;
        Self::from_json(&text, Path::new(name_or_path))
    }

    /// Parses and validates the JSON text of `file` (the path is only used in errors).
    pub fn from_json(text: &str, file: &Path) -> Result<Self, ScenarioError> {
        let file = file.display().to_string();
        let s: Self = serde_json::from_str(text).map_err(|e| {
            let full = e.to_string();
            let message = full
                .rsplit_once(" at line ")
                .map_or(full.as_str(), |(m, _)| m)
                .to_owned();
            ScenarioError::Parse {
                file: file.clone(),
                line: e.line(),
                column: e.column(),
                message,
            }
        })?;
        s.validate(&Source::File(file))?;
        Ok(s)
    }

    /// Pretty JSON (the structure [`Self::from_json`] reads).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Checks what the types cannot: finite numbers, references, lengths, unique ids.
    pub fn validate(&self, source: &Source) -> Result<(), ScenarioError> {
        let bad = |message: String| ScenarioError::Invalid {
            origin: source.to_string(),
            message,
        };
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let o = &self.origin;
        if !(o.lat_deg.abs() <= 90.0 && o.lon_deg.abs() <= 180.0 && o.alt_m.is_finite()) {
            return Err(bad(format!("origin {o:?} is not a valid geodetic point")));
        }
        if self.targets.is_empty() {
            return Err(bad("targets is empty".into()));
        }
        if self.sensors.is_empty() {
            return Err(bad("sensors is empty".into()));
        }
        unique(self.targets.iter().map(|t| t.id.as_str()), "targets").map_err(&bad)?;
        unique(self.sensors.iter().map(|s| s.id.as_str()), "sensors").map_err(&bad)?;
        unique(self.roads.iter().map(|r| r.id.as_str()), "roads").map_err(&bad)?;
        for (i, r) in self.roads.iter().enumerate() {
            harrier_core::road::Road::from_scenario(r)
                .map_err(|e| bad(format!("roads[{i}] ({}): {e}", r.id)))?;
        }
        let mut z = None;
        for (i, t) in self.targets.iter().enumerate() {
            let at = |m: &str| bad(format!("targets[{i}] ({}): {m}", t.id));
            if !(t.size_m.is_finite() && t.size_m > 0.0) {
                return Err(at("size_m must be > 0"));
            }
            let j = &t.jitter;
            if !finite(&[j.position_m, j.heading_deg, j.speed_mps]) {
                return Err(at("jitter must be finite"));
            }
            let tz = match &t.motion {
                TargetMotion::Road {
                    road,
                    speed_mps,
                    start_m,
                    lateral_std_m,
                } => {
                    if !self.roads.iter().any(|r| &r.id == road) {
                        return Err(at(&format!("road {road:?} is not in roads")));
                    }
                    if !(finite(&[*speed_mps, *start_m, *lateral_std_m]) && *speed_mps > 0.0) {
                        return Err(at(
                            "speed_mps must be > 0, start_m and lateral_std_m finite",
                        ));
                    }
                    0.0
                }
                TargetMotion::Segments {
                    position,
                    velocity,
                    z_m,
                    segments,
                } => {
                    let ok = finite(position)
                        && finite(velocity)
                        && z_m.is_finite()
                        && segments
                            .iter()
                            .all(|s| s.turn_rate.is_finite() && s.duration_s > 0.0);
                    if !ok {
                        return Err(at("segments need finite numbers and durations > 0"));
                    }
                    *z_m
                }
                TargetMotion::Leader {
                    position,
                    z_m,
                    speed_mps,
                    heading_deg,
                    amplitude_deg,
                    period_s,
                } => {
                    let ok = finite(position)
                        && finite(&[*z_m, *heading_deg, *amplitude_deg])
                        && *speed_mps > 0.0
                        && speed_mps.is_finite()
                        && *period_s > 0.0
                        && period_s.is_finite();
                    if !ok {
                        return Err(at("leader needs finite numbers, speed and period > 0"));
                    }
                    *z_m
                }
            };
            match z {
                None => z = Some(tz),
                Some(z0) if z0 != tz => {
                    return Err(at(&format!(
                        "altitude {tz} m differs from the first target's {z0} m \
                         (all targets share one plane)"
                    )));
                }
                _ => {}
            }
        }
        for (i, s) in self.sensors.iter().enumerate() {
            let at = |m: &str| bad(format!("sensors[{i}] ({}): {m}", s.id));
            if s.id.is_empty() {
                return Err(at("id is empty"));
            }
            if !(s.rate_hz > 0.0 && s.rate_hz <= 1000.0) {
                return Err(at("rate_hz must be in (0, 1000]"));
            }
            if !((0.0..=1.0).contains(&s.pd) && s.clutter_rate >= 0.0 && s.clutter_rate <= 1e4) {
                return Err(at("pd must be in [0, 1] and clutter_rate in [0, 10000]"));
            }
            if !(s.max_range_m > 0.0 && s.max_range_m.is_finite()) {
                return Err(at("max_range_m must be > 0"));
            }
            if !s.noise_std.iter().all(|v| v.is_finite() && *v > 0.0) {
                return Err(at("noise_std must be finite and > 0"));
            }
            if !(s.time_offset_s.is_finite() && s.time_offset_s.abs() <= 5.0) {
                return Err(at("time_offset_s must be within ±5 s"));
            }
            let n = s.kind().len(Some(2));
            if s.noise_std.len() != n {
                return Err(at(&format!(
                    "noise_std has {} components, {:?} needs {n}",
                    s.noise_std.len(),
                    s.kind()
                )));
            }
            match &s.model {
                SensorType::Camera {
                    fov_deg,
                    pointing,
                    mounting_deg,
                    ..
                } => {
                    if !(*fov_deg > 0.0 && *fov_deg < 180.0) {
                        return Err(at("fov_deg must be in (0, 180)"));
                    }
                    if !mounting_deg.iter().all(|d| d.abs() <= 10.0) {
                        return Err(at("mounting_deg must be within ±10 degrees"));
                    }
                    match pointing {
                        Pointing::Fixed {
                            pan_deg,
                            depression_deg,
                        } if !(pan_deg.is_finite() && depression_deg.abs() <= 90.0) => {
                            return Err(at("pointing needs a finite pan and |depression| <= 90"));
                        }
                        Pointing::Track { target } if *target >= self.targets.len() => {
                            return Err(at(&format!("pointing.target {target} does not exist")));
                        }
                        _ => {}
                    }
                }
                SensorType::Radar { bias, .. } => {
                    let ok = match bias {
                        BiasModel::None => true,
                        BiasModel::Abrupt {
                            t_on,
                            t_off,
                            scale,
                            offset,
                        } => finite(&[*t_on, *t_off]) && finite(scale) && finite(offset),
                        BiasModel::Markov {
                            mean,
                            std,
                            tau_s,
                            scale,
                        } => {
                            finite(mean)
                                && finite(scale)
                                && std.iter().all(|v| v.is_finite() && *v >= 0.0)
                                && tau_s.is_finite()
                                && *tau_s > 0.0
                        }
                    };
                    if !ok {
                        return Err(at("bias needs finite numbers, std >= 0 and tau_s > 0"));
                    }
                }
            }
        }
        let v = &self.vehicles;
        if !(v.preroll_s.is_finite() && (0.0..=3600.0).contains(&v.preroll_s)) {
            return Err(bad("vehicles.preroll_s must be in [0, 3600]".into()));
        }
        let behaviour_ok = match &v.behaviour {
            Behaviour::Orbit {
                target,
                radius_m,
                height_m,
                speed_mps,
            } => {
                *target < self.targets.len()
                    && finite(&[*radius_m, *height_m, *speed_mps])
                    && *radius_m > 0.0
                    && *speed_mps > 0.0
            }
            Behaviour::Follow {
                target,
                offset_m,
                height_m,
                spacing_m,
            } => {
                *target < self.targets.len() && finite(offset_m) && finite(&[*height_m, *spacing_m])
            }
            Behaviour::Hold {
                position,
                spacing_m,
            } => finite(position) && spacing_m.is_finite(),
            Behaviour::Cruise {
                velocity,
                altitude_m,
            } => finite(velocity) && altitude_m.is_finite() && *altitude_m > 0.0,
        };
        if !behaviour_ok {
            return Err(bad(
                "vehicles.behaviour: target index out of range or a number is not finite/positive"
                    .into(),
            ));
        }
        let h = &self.estimator;
        if !h.prior_std.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(bad("estimator.prior_std must be finite and > 0".into()));
        }
        Ok(())
    }
}

fn unique<'a>(ids: impl Iterator<Item = &'a str>, what: &str) -> Result<(), String> {
    let mut seen: Vec<&str> = Vec::new();
    for id in ids {
        if id.is_empty() {
            return Err(format!("{what}: an id is empty"));
        }
        if seen.contains(&id) {
            return Err(format!("{what}: id {id:?} appears twice"));
        }
        seen.push(id);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_err(text: &str) -> String {
        SimScenario::from_json(text, Path::new("bad/scn.json"))
            .expect_err("refused")
            .to_string()
    }

    #[test]
    fn bad_files_name_file_line_and_problem() {
        let good = SimScenario::preset("cimm-road").expect("preset").to_json();
        // Syntax error on line 3.
        let mut lines: Vec<&str> = good.lines().collect();
        lines[2] = "  \"description\": oops,";
        let e = parse_err(&lines.join("\n"));
        assert!(e.starts_with("bad/scn.json:3:"), "{e}");
        // Out-of-range values are refused at their line.
        for (from, to, what) in [
            ("\"rate_hz\": 1.0", "\"rate_hz\": -1.0", "must be > 0"),
            ("\"pd\": 1.0", "\"pd\": 1.5", "probability"),
            ("\"fov_deg\": 30.0", "\"fov_deg\": 0.0", "must be > 0"),
            ("\"clutter_rate\": 0.0", "\"clutter_rate\": -2", ">= 0"),
        ] {
            let text = good.replace(from, to);
            let line = text.lines().position(|l| l.contains(to.trim())).expect(to) + 1;
            let e = parse_err(&text);
            // The value's line, or the end of the tagged object (`model`) holding it.
            let at: usize = e
                .strip_prefix("bad/scn.json:")
                .and_then(|r| r.split(':').next())
                .and_then(|l| l.parse().ok())
                .expect("line number");
            assert!((line..line + 8).contains(&at), "{e} (value on line {line})");
            assert!(e.contains(what), "{e}");
        }
        let e = parse_err(&good.replace("\"speed_mps\": 10.0", "\"speeed\": 10.0"));
        assert!(
            e.contains("unknown field") && e.contains("bad/scn.json:"),
            "{e}"
        );
        // Consistency problems name the field.
        let e = parse_err(&good.replace("\"road\": \"road1\"", "\"road\": \"road9\""));
        assert!(e.contains("targets[0] (tgt)") && e.contains("road9"), "{e}");
        let e = parse_err(&good.replace("\"fov_deg\": 30.0", "\"fov_deg\": 200.0"));
        assert!(e.contains("fov_deg must be in (0, 180)"), "{e}");
        let e = parse_err(&good.replace(
            "\"clutter_rate\": 0.0,",
            "\"clutter_rate\": 0.0, \"time_offset_s\": 9.0,",
        ));
        assert!(e.contains("time_offset_s must be within ±5 s"), "{e}");
        let e = parse_err(&good.replace("10.0,\n        10.0", "10.0"));
        assert!(e.contains("noise_std has 1 components"), "{e}");
        let e = SimScenario::load("/nonexistent/x.json").expect_err("missing");
        assert!(e.to_string().contains("cimm-road"), "{e}");
    }
}
