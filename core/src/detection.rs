//! The detection message schema: what a UAV's sensors publish (over Zenoh, by harrier-sim; read by
//! the server), defined once here and documented in `DETECTIONS.md`.
//!
//! One [`DetectionScan`] is one scan of one sensor: the sensor, the platform's pose at the scan
//! time, the noise of every detection in it, and zero or more detections (a scan with no detection
//! is still published, so a subscriber sees missed scans and the rate). Each detection's `z` has
//! the layout, units and angle conventions of `gcs-scenario/1` (FORMAT.md §1 and §3): ENU frame,
//! azimuth clockwise from North wrapped to `[-π, π)`, elevation above the horizontal.
//!
//! Truth ([`TruthSample`]) travels on its own key and exists only in simulation, for scoring.
//!
//! Both are JSON (`application/json`, schema [`DETECTIONS_SCHEMA`] / [`TRUTH_SCHEMA`]).
//! [`DetectionScan::from_json`] checks everything a subscriber relies on, so a malformed payload
//! is rejected with a message that names the field, never half-used.

use serde::{Deserialize, Serialize};

use crate::measurement::MeasKind;

/// Value of [`DetectionScan::schema`].
pub const DETECTIONS_SCHEMA: &str = "harrier-detections/1";
/// Value of [`TruthSample::schema`].
pub const TRUTH_SCHEMA: &str = "harrier-truth/1";
/// Zenoh key expression matching every vehicle's detections.
pub const DETECTIONS_KEY_ALL: &str = "harrier/v1/vehicle/*/detections";
/// Zenoh key of the simulation's ground truth.
pub const TRUTH_KEY: &str = "harrier/v1/sim/truth";
/// Zenoh key on which a ground station publishes its tracks (`harrier-tracks/1`, DETECTIONS.md).
pub const TRACKS_KEY: &str = "harrier/v1/tracks";
/// Schema of a ground station's track message.
pub const TRACKS_SCHEMA: &str = "harrier-tracks/1";

/// Largest magnitude (m, m/s) of a platform position or velocity component, a `position`
/// detection's coordinate or a range, a truth state component, and of the origin's altitude,
/// that a payload may carry:
/// ten times the geostationary radius. Beyond it a consumer's frame conversion (through ECEF)
/// overflows to NaN — found by fuzzing (`fuzz/regressions/detections/`): a `position` fix at
/// 3·10⁷⁴ m passed validation and became `[NaN, NaN]` in harrier-link's `scan_in_frame`.
pub const MAX_DISTANCE_M: f64 = 1e8;

/// The Zenoh key on which vehicle `id` publishes its detections.
pub fn detections_key(vehicle: u8) -> String {
    format!("harrier/v1/vehicle/{vehicle}/detections")
}

/// A geodetic position (WGS-84).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct GeoPoint {
    /// Latitude (degrees).
    pub lat_deg: f64,
    /// Longitude (degrees).
    pub lon_deg: f64,
    /// Altitude above mean sea level (m).
    pub alt_m: f64,
}

impl GeoPoint {
    /// A geodetic position from degrees and metres.
    pub fn new(lat_deg: f64, lon_deg: f64, alt_m: f64) -> Self {
        Self {
            lat_deg,
            lon_deg,
            alt_m,
        }
    }
}

/// The pose of the sensor's platform at the scan time.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct PlatformPose {
    /// ENU position (m) in the frame whose origin is [`DetectionScan::origin`].
    pub pos: [f64; 3],
    /// ENU velocity (m/s).
    pub vel: [f64; 3],
    /// Attitude `[roll, pitch, yaw]` (rad; yaw clockwise from North, as MAVLink ATTITUDE).
    pub attitude: [f64; 3],
    /// The same position, geodetic (WGS-84). Optional on the wire: a reader that needs it derives
    /// it from `pos` and the scan's `origin` when it is absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geodetic: Option<GeoPoint>,
}

/// One detection: a measurement that a target (or clutter: nothing says which) produced.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Detection {
    /// Measured value, layout by [`DetectionScan::kind`] (FORMAT.md §3).
    pub z: Vec<f64>,
}

/// One scan of one sensor of one vehicle.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct DetectionScan {
    /// Always [`DETECTIONS_SCHEMA`].
    pub schema: String,
    /// Scan time (s since the simulation's epoch; a live vehicle's clock).
    pub t: f64,
    /// The same instant as UNIX time (s since 1970-01-01 UTC) on the sender's clock, so that scans
    /// from several processes and hosts can be put on one time line. Optional: older senders and
    /// recordings leave it out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_unix: Option<f64>,
    /// MAVLink system id of the vehicle.
    pub vehicle: u8,
    /// Scan counter of this sensor, +1 per scan (gaps reveal lost messages).
    pub seq: u64,
    /// Sensor id, unique on the vehicle (e.g. `cam`, `radar`).
    pub sensor: String,
    /// Measurement kind of every detection.
    pub kind: MeasKind,
    /// Geodetic origin of the ENU frame of `platform.pos` and of `position` detections.
    pub origin: GeoPoint,
    /// Platform pose at `t`.
    pub platform: PlatformPose,
    /// Standard deviation of each component of `z` (Gaussian, independent).
    pub noise_std: Vec<f64>,
    /// Detections (may be empty).
    pub detections: Vec<Detection>,
}

/// A malformed detection or truth payload.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("malformed {what} payload: {message}")]
pub struct PayloadError {
    /// `detections` or `truth`.
    pub what: &'static str,
    /// What is wrong (names the field).
    pub message: String,
}

fn check(
    cond: bool,
    what: &'static str,
    message: impl FnOnce() -> String,
) -> Result<(), PayloadError> {
    if cond {
        Ok(())
    } else {
        Err(PayloadError {
            what,
            message: message(),
        })
    }
}

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Finite and within ±[`MAX_DISTANCE_M`].
fn all_bounded(v: &[f64]) -> bool {
    v.iter().all(|x| x.abs() <= MAX_DISTANCE_M)
}

/// A valid WGS-84 point: latitude in [-90, 90], longitude in [-180, 180], bounded altitude.
fn valid_geo(g: &GeoPoint) -> bool {
    g.lat_deg.abs() <= 90.0 && g.lon_deg.abs() <= 180.0 && g.alt_m.abs() <= MAX_DISTANCE_M
}

impl DetectionScan {
    /// Number of components of each detection's `z`.
    pub fn dim(&self) -> usize {
        match self.kind {
            MeasKind::Position => self.noise_std.len(),
            k => k.len(None),
        }
    }

    /// Checks what a subscriber relies on: schema, finite numbers, `z` and `noise_std` lengths
    /// matching the kind, positive noise, angles in range.
    pub fn validate(&self) -> Result<(), PayloadError> {
        const W: &str = "detections";
        check(self.schema == DETECTIONS_SCHEMA, W, || {
            format!("schema {:?}, expected {DETECTIONS_SCHEMA:?}", self.schema)
        })?;
        check(self.t.is_finite(), W, || {
            format!("t = {} is not finite", self.t)
        })?;
        check(
            self.time_unix.is_none_or(|u| u.is_finite() && u > 0.0),
            W,
            || {
                format!(
                    "time_unix = {:?} is not a positive finite number",
                    self.time_unix
                )
            },
        )?;
        check(!self.sensor.is_empty(), W, || "sensor id is empty".into())?;
        check(valid_geo(&self.origin), W, || {
            format!("origin {:?} is not a valid WGS-84 point", self.origin)
        })?;
        let p = &self.platform;
        check(
            all_finite(&p.pos) && all_finite(&p.vel) && all_finite(&p.attitude),
            W,
            || "platform pose has a non-finite number".into(),
        )?;
        check(all_bounded(&p.pos) && all_bounded(&p.vel), W, || {
            format!(
                "platform pos/vel beyond ±{MAX_DISTANCE_M:e}: {:?} {:?}",
                p.pos, p.vel
            )
        })?;
        let n = self.dim();
        let expected = match self.kind {
            MeasKind::Position => (2..=3).contains(&n),
            _ => self.noise_std.len() == n,
        };
        check(expected, W, || {
            format!(
                "noise_std has {} components, which does not fit kind {:?}",
                self.noise_std.len(),
                self.kind
            )
        })?;
        check(
            self.noise_std.iter().all(|s| s.is_finite() && *s > 0.0),
            W,
            || format!("noise_std {:?} must be finite and > 0", self.noise_std),
        )?;
        for (i, d) in self.detections.iter().enumerate() {
            check(d.z.len() == n, W, || {
                format!(
                    "detections[{i}].z has {} components, expected {n}",
                    d.z.len()
                )
            })?;
            check(all_finite(&d.z), W, || {
                format!("detections[{i}].z = {:?} is not finite", d.z)
            })?;
            if let Some(a) = self.kind.azimuth_index() {
                check(d.z[a].abs() <= std::f64::consts::PI + 1e-9, W, || {
                    format!(
                        "detections[{i}].z[{a}] (azimuth) = {} is outside [-pi, pi]",
                        d.z[a]
                    )
                })?;
            }
            if matches!(self.kind, MeasKind::AzEl | MeasKind::BearingSize) {
                check(
                    d.z[1].abs() <= std::f64::consts::FRAC_PI_2 + 1e-9,
                    W,
                    || {
                        format!(
                            "detections[{i}].z[1] (elevation) = {} is outside [-pi/2, pi/2]",
                            d.z[1]
                        )
                    },
                )?;
            }
            if self.kind == MeasKind::RangeBearing {
                check(d.z[0] >= 0.0, W, || {
                    format!("detections[{i}].z[0] (range) = {} is negative", d.z[0])
                })?;
            }
            let distances = match self.kind {
                MeasKind::Position => &d.z[..],
                MeasKind::RangeBearing => &d.z[..1],
                MeasKind::AzEl | MeasKind::BearingSize => &[],
            };
            check(all_bounded(distances), W, || {
                format!(
                    "detections[{i}].z = {:?} has a distance beyond ±{MAX_DISTANCE_M:e} m",
                    d.z
                )
            })?;
        }
        Ok(())
    }

    /// Serialises to JSON.
    pub fn to_json(&self) -> String {
        // Plain data with string keys: serialisation cannot fail.
        serde_json::to_string(self).unwrap_or_default()
    }

    /// Parses and [validates](Self::validate) a payload.
    pub fn from_json(bytes: &[u8]) -> Result<Self, PayloadError> {
        let scan: Self = serde_json::from_slice(bytes).map_err(|e| PayloadError {
            what: "detections",
            message: e.to_string(),
        })?;
        scan.validate()?;
        Ok(scan)
    }
}

/// The true state of one target.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct TargetTruth {
    /// Target id.
    pub id: String,
    /// Canonical state `[x, y, z, vx, vy, vz]` (ENU, m and m/s).
    pub state: [f64; 6],
    /// Motion mode in force (e.g. `CV`, `left`, `right`).
    pub mode: String,
}

/// Simulation-only ground truth at one time.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct TruthSample {
    /// Always [`TRUTH_SCHEMA`].
    pub schema: String,
    /// Time (s, the detections' clock).
    pub t: f64,
    /// The same instant as UNIX time, as in [`DetectionScan::time_unix`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_unix: Option<f64>,
    /// Geodetic origin of the ENU frame.
    pub origin: GeoPoint,
    /// Every target.
    pub targets: Vec<TargetTruth>,
}

impl TruthSample {
    /// Serialises to JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }

    /// Parses and checks a payload (schema, a WGS-84 origin, states finite and within
    /// ±[`MAX_DISTANCE_M`]).
    pub fn from_json(bytes: &[u8]) -> Result<Self, PayloadError> {
        const W: &str = "truth";
        let s: Self = serde_json::from_slice(bytes).map_err(|e| PayloadError {
            what: W,
            message: e.to_string(),
        })?;
        check(s.schema == TRUTH_SCHEMA, W, || {
            format!("schema {:?}, expected {TRUTH_SCHEMA:?}", s.schema)
        })?;
        check(s.t.is_finite(), W, || format!("t = {} is not finite", s.t))?;
        check(valid_geo(&s.origin), W, || {
            format!("origin {:?} is not a valid WGS-84 point", s.origin)
        })?;
        for t in &s.targets {
            check(all_finite(&t.state), W, || {
                format!("target {:?} state {:?} is not finite", t.id, t.state)
            })?;
            // As for detections: a session export takes every state into another frame.
            check(all_bounded(&t.state), W, || {
                format!(
                    "target {:?} state {:?} is beyond ±{MAX_DISTANCE_M:e}",
                    t.id, t.state
                )
            })?;
        }
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan() -> DetectionScan {
        DetectionScan {
            time_unix: Some(1.8e9),
            schema: DETECTIONS_SCHEMA.into(),
            t: 12.5,
            vehicle: 2,
            seq: 125,
            sensor: "cam".into(),
            kind: MeasKind::AzEl,
            origin: GeoPoint {
                lat_deg: 47.39,
                lon_deg: 8.54,
                alt_m: 488.0,
            },
            platform: PlatformPose {
                pos: [10.0, 20.0, 100.0],
                vel: [5.0, 0.0, 0.0],
                attitude: [0.0, 0.0, 1.57],
                geodetic: Some(GeoPoint {
                    lat_deg: 47.3902,
                    lon_deg: 8.5401,
                    alt_m: 588.0,
                }),
            },
            noise_std: vec![0.002, 0.002],
            detections: vec![Detection { z: vec![0.3, -1.2] }],
        }
    }

    #[test]
    fn round_trips_and_keys() {
        let s = scan();
        let back = DetectionScan::from_json(s.to_json().as_bytes()).expect("valid");
        assert_eq!(back, s);
        assert_eq!(detections_key(7), "harrier/v1/vehicle/7/detections");
        let json: serde_json::Value = serde_json::from_str(&s.to_json()).expect("json");
        assert_eq!(json["kind"], "az_el");
        assert_eq!(json["platform"]["geodetic"]["alt_m"], 588.0);
    }

    #[test]
    fn malformed_payloads_name_the_problem() {
        type Mutation = fn(&mut DetectionScan);
        let cases: [(Mutation, &str); 13] = [
            (|s| s.schema = "x".into(), "schema"),
            // Found by fuzzing: valid JSON numbers a consumer's frame conversion cannot take.
            (|s| s.origin.lat_deg = 91.0, "origin"),
            (|s| s.origin.alt_m = 1e300, "origin"),
            (|s| s.platform.pos[2] = 3e74, "platform pos/vel beyond"),
            (|s| s.platform.vel[0] = -1e300, "platform pos/vel beyond"),
            (|s| s.time_unix = Some(-1.0), "time_unix"),
            (|s| s.t = f64::NAN, "t = NaN"),
            (|s| s.detections[0].z = vec![0.1], "detections[0].z has 1"),
            (|s| s.detections[0].z[0] = 4.0, "azimuth"),
            (|s| s.detections[0].z[1] = 2.0, "elevation"),
            (|s| s.noise_std = vec![0.0, 1.0], "noise_std"),
            (|s| s.noise_std = vec![1.0], "noise_std has 1"),
            (|s| s.platform.pos[0] = f64::INFINITY, "platform"),
        ];
        for (mutate, expected) in cases {
            let mut s = scan();
            mutate(&mut s);
            let e = s.validate().expect_err(expected);
            assert!(e.to_string().contains(expected), "{e} lacks {expected:?}");
        }
        let e = DetectionScan::from_json(b"{\"schema\": 1}").expect_err("bad json");
        assert!(
            e.to_string().starts_with("malformed detections payload"),
            "{e}"
        );
        let mut pos = scan();
        pos.kind = MeasKind::Position;
        pos.noise_std = vec![10.0, 10.0];
        pos.detections[0].z = vec![100.0, -50.0];
        pos.validate().expect("2-component position");
        // fuzz/regressions/detections/position-3e74: a fix beyond any frame conversion.
        pos.detections[0].z[0] = 3.3e74;
        let e = pos.validate().expect_err("3e74 m");
        assert!(e.to_string().contains("distance beyond"), "{e}");
        pos.detections[0].z[0] = 100.0;
        pos.noise_std = vec![10.0; 4];
        assert!(pos.validate().is_err());
        // `time_unix` is optional: a payload without it (an older sender) still reads.
        let mut old: serde_json::Value = serde_json::from_str(&scan().to_json()).unwrap();
        assert_eq!(old["time_unix"], 1.8e9);
        old.as_object_mut().unwrap().remove("time_unix");
        let back = DetectionScan::from_json(old.to_string().as_bytes()).unwrap();
        assert_eq!(back.time_unix, None);
    }

    #[test]
    fn truth_round_trips() {
        let t = TruthSample {
            schema: TRUTH_SCHEMA.into(),
            t: 1.0,
            time_unix: Some(1.8e9 + 1.0),
            origin: scan().origin,
            targets: vec![TargetTruth {
                id: "T0".into(),
                state: [1.0, 2.0, 0.0, 3.0, 4.0, 0.0],
                mode: "CV".into(),
            }],
        };
        assert_eq!(
            TruthSample::from_json(t.to_json().as_bytes()),
            Ok(t.clone())
        );
        let bad = t.to_json().replace("3.0", "1e999");
        assert!(TruthSample::from_json(bad.as_bytes()).is_err());
        // fuzz/regressions/detections/truth-state-1e308.json: overflows a frame change.
        let huge = t.to_json().replace("3.0", "1.7e308");
        assert!(TruthSample::from_json(huge.as_bytes()).is_err());
        let pole = t.to_json().replace("47.39", "147.39");
        assert!(TruthSample::from_json(pole.as_bytes()).is_err());
    }
}
