//! The sensors a vehicle carries: gimbal cameras (`az_el`, `bearing_size`, or ground
//! `position` by geolocation) and radars (`range_bearing` with the bias models of \[ICDKF\]), each
//! scanning at its own rate and producing one [`DetectionScan`] per scan.
//!
//! Per scan and sensor: every target inside the field of view (a cone of half-angle `fov/2`
//! about the boresight for cameras; all around for radars) and within `max_range_m` is detected
//! with probability `pd`; the noise-free value `h` comes from harrier-core's measurement models
//! ([`harrier_core::measurement`], FORMAT.md §1/§3 conventions), Gaussian noise of `noise_std` is
//! added, azimuths are wrapped to `[-π, π)` and elevations kept in `[-π/2, π/2]`. A Poisson number
//! of clutter detections (mean `clutter_rate`) falls uniformly in the field of view: directions
//! uniform over the cone's solid angle (cameras; geolocated onto the target plane for `position`
//! output, range uniform up to `max_range_m` for `bearing_size`), range and azimuth uniform for
//! radars. A radar with `paints_vehicles` also detects the other vehicles
//! ([`SensorSuite::set_vehicles`]), as it does the targets: cooperative targets whose GPS
//! position the ground station knows. Detections are shuffled, so their order reveals nothing;
//! [`LabelledScan::sources`] keeps which target made each (simulation only).
//!
//! Randomness: one ChaCha8 stream per (vehicle, sensor) from the run's seed, so adding a vehicle
//! or a sensor never changes another one's noise; every scan draws the same numbers whatever was
//! detected, so changing `pd` or the geometry does not reshuffle later noise.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use harrier_core::detection::{
    DETECTIONS_SCHEMA, Detection, DetectionScan, GeoPoint, PlatformPose,
};
use harrier_core::linalg::wrap_angle;
use harrier_core::measurement::{
    AzEl, BearingSize, Geometry, MeasKind, MeasurementModel, RangeBearing, TargetSize,
};
use nalgebra::{SVector, Vector3};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};

use crate::setup::{
    BiasModel, Pointing, ScenarioError, SensorSpec, SensorType, SimScenario, Source,
};
use crate::vehicle::Vehicle;
use crate::world::World;

/// ChaCha stream of sensor `index` on vehicle `vehicle` (the world uses stream 0).
fn sensor_stream(vehicle: u8, index: usize) -> u64 {
    (1 << 32) | (u64::from(vehicle) << 16) | (index as u64 & 0xffff)
}

/// A scan with, for each detection, the index of the target that produced it (`None`: clutter;
/// an index past the world's targets: that vehicle of [`SensorSuite::set_vehicles`]'s list, in
/// its order).
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledScan {
    /// The published scan.
    pub scan: DetectionScan,
    /// Aligned with `scan.detections`.
    pub sources: Vec<Option<usize>>,
}

#[derive(Debug, Clone)]
struct SensorState {
    spec: SensorSpec,
    kind: MeasKind,
    rng: ChaCha8Rng,
    poisson: Option<Poisson<f64>>,
    seq: u64,
    next_k: u64,
    /// Markov bias offsets and the time they hold for.
    markov: Option<([f64; 2], f64)>,
}

/// The sensors of one vehicle.
#[derive(Debug, Clone)]
pub struct SensorSuite {
    sensors: Vec<SensorState>,
    sizes: Vec<f64>,
    plane_z: f64,
    /// Where the vehicle's gimbal points (unit ENU), for cameras with `pointing: roi`.
    gimbal: Option<Vector3<f64>>,
    /// The other vehicles' positions (ENU), for radars that paint them.
    vehicles: Vec<Vector3<f64>>,
}

/// The pose of a simulated vehicle as published with its detections: ENU position and velocity,
/// attitude and geodetic position.
pub fn platform_pose(v: &Vehicle) -> PlatformPose {
    let s = v.state();
    PlatformPose {
        pos: [s.position.x, s.position.y, s.position.z],
        vel: [s.velocity.x, s.velocity.y, s.velocity.z],
        attitude: v.attitude(),
        geodetic: Some(v.position()),
    }
}

/// Azimuth (clockwise from North, `[-π, π)`) and elevation of a direction (FORMAT.md §1).
fn az_el_of(d: &Vector3<f64>) -> [f64; 2] {
    [wrap_angle(d.x.atan2(d.y)), d.z.atan2(d.x.hypot(d.y))]
}

/// A unit vector uniformly distributed over the solid angle of the cone of half-angle `half`
/// about the unit vector `b`.
fn in_cone(rng: &mut ChaCha8Rng, b: &Vector3<f64>, half: f64) -> Vector3<f64> {
    let cos_t = 1.0 - rng.random::<f64>() * (1.0 - half.cos());
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = rng.random_range(0.0..TAU);
    let helper = if b.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let e1 = b.cross(&helper).normalize();
    let e2 = b.cross(&e1);
    b * cos_t + (e1 * phi.cos() + e2 * phi.sin()) * sin_t
}

impl SensorSuite {
    /// The sensors of `scenario` on vehicle `vehicle`, with noise streams drawn from `seed`.
    pub fn new(scenario: &SimScenario, seed: u64, vehicle: u8) -> Result<Self, ScenarioError> {
        scenario.validate(&Source::Named(scenario.name.clone()))?;
        let sensors = scenario
            .sensors
            .iter()
            .enumerate()
            .map(|(i, spec)| {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(sensor_stream(vehicle, i));
                SensorState {
                    kind: spec.kind(),
                    spec: spec.clone(),
                    rng,
                    // `validate` bounds the rate to [0, 1e4]; Poisson needs it > 0.
                    poisson: Poisson::new(spec.clutter_rate).ok(),
                    seq: 0,
                    next_k: 0,
                    markov: None,
                }
            })
            .collect();
        Ok(Self {
            sensors,
            sizes: scenario.targets.iter().map(|t| t.size_m).collect(),
            plane_z: scenario.plane_z(),
            gimbal: None,
            vehicles: Vec::new(),
        })
    }

    /// Points the vehicle's gimbal (unit ENU direction, `Vehicle::gimbal_direction`; `None`:
    /// no region of interest) for the next scans of its `roi` cameras.
    pub fn set_gimbal(&mut self, direction: Option<Vector3<f64>>) {
        self.gimbal = direction.filter(|d| d.iter().all(|x| x.is_finite()));
    }

    /// Whether one of its sensors paints the other vehicles (a radar with `paints_vehicles`):
    /// only then do its scans need [`Self::set_vehicles`].
    pub fn paints_vehicles(&self) -> bool {
        self.sensors.iter().any(SensorState::paints_vehicles)
    }

    /// Where the other vehicles are (ENU positions) for the next scans of radars with
    /// `paints_vehicles` (none until set).
    pub fn set_vehicles(&mut self, positions: impl IntoIterator<Item = Vector3<f64>>) {
        self.vehicles.clear();
        self.vehicles.extend(
            positions
                .into_iter()
                .filter(|p| p.iter().all(|x| x.is_finite())),
        );
    }

    /// One [`DetectionScan`] per sensor due at `t` (each scans at `k / rate_hz`; a sensor whose
    /// scan time was passed over scans once at the next call).
    pub fn scan(
        &mut self,
        t: f64,
        vehicle_id: u8,
        pose: &PlatformPose,
        origin: GeoPoint,
        world: &World,
    ) -> Vec<DetectionScan> {
        self.scan_labelled(t, vehicle_id, pose, origin, world)
            .into_iter()
            .map(|l| l.scan)
            .collect()
    }

    /// [`Self::scan`] with the source of every detection.
    pub fn scan_labelled(
        &mut self,
        t: f64,
        vehicle_id: u8,
        pose: &PlatformPose,
        origin: GeoPoint,
        world: &World,
    ) -> Vec<LabelledScan> {
        if !t.is_finite() {
            return Vec::new();
        }
        let due: Vec<bool> = self.sensors.iter_mut().map(|s| s.due(t)).collect();
        if !due.contains(&true) {
            return Vec::new();
        }
        let targets: Vec<Vector3<f64>> = world
            .truth()
            .iter()
            .map(|s| Vector3::new(s.state[0], s.state[1], s.state[2]))
            .collect();
        // The targets, then the other vehicles, for the radars that paint them (the other
        // sensors' draws stay as they were).
        let painted: Vec<Vector3<f64>> = if self.vehicles.is_empty() {
            Vec::new()
        } else {
            targets.iter().chain(&self.vehicles).copied().collect()
        };
        let (sizes, plane_z, gimbal) = (&self.sizes, self.plane_z, self.gimbal);
        let mut out = Vec::new();
        for (s, _) in self.sensors.iter_mut().zip(due).filter(|(_, d)| *d) {
            let paints = s.paints_vehicles() && !painted.is_empty();
            let truths = if paints { &painted } else { &targets };
            let (detections, sources) = s.detect(t, pose, truths, sizes, plane_z, gimbal);
            let scan = DetectionScan {
                schema: DETECTIONS_SCHEMA.into(),
                // Taken at t, stamped with the sensor's time offset.
                t: t + s.spec.time_offset_s,
                time_unix: None,
                vehicle: vehicle_id,
                seq: s.seq,
                sensor: s.spec.id.clone(),
                kind: s.kind,
                origin,
                platform: *pose,
                noise_std: s.spec.noise_std.clone(),
                detections,
            };
            s.seq += 1;
            out.push(LabelledScan { scan, sources });
        }
        out
    }
}

impl SensorState {
    /// A radar that paints the other vehicles.
    fn paints_vehicles(&self) -> bool {
        matches!(
            self.spec.model,
            SensorType::Radar {
                paints_vehicles: true,
                ..
            }
        )
    }

    /// Whether a scan is due at `t`; moves the schedule past `t`.
    fn due(&mut self, t: f64) -> bool {
        let k = (t * self.spec.rate_hz + 1e-6).floor();
        if k < 0.0 || k < self.next_k as f64 {
            return false;
        }
        self.next_k = k as u64 + 1;
        true
    }

    fn boresight(
        &self,
        pose: &PlatformPose,
        truths: &[Vector3<f64>],
        gimbal: Option<Vector3<f64>>,
    ) -> Vector3<f64> {
        let nadir = -Vector3::z();
        let SensorType::Camera { pointing, .. } = &self.spec.model else {
            return nadir;
        };
        match *pointing {
            Pointing::Nadir => nadir,
            Pointing::Fixed {
                pan_deg,
                depression_deg,
            } => {
                let az = pose.attitude[2] + pan_deg.to_radians();
                let dep = depression_deg.to_radians();
                Vector3::new(az.sin() * dep.cos(), az.cos() * dep.cos(), -dep.sin())
            }
            Pointing::Track { target } => truths
                .get(target)
                .map(|p| p - Vector3::from(pose.pos))
                .and_then(|d| d.try_normalize(1e-9))
                .unwrap_or(nadir),
            Pointing::Roi => gimbal.unwrap_or(nadir),
        }
    }

    /// Bias `(scale, offset)` at `t` (\[ICDKF\] eq. (9)); draws two normals per scan for Markov.
    fn bias(&mut self, t: f64) -> ([f64; 2], [f64; 2]) {
        let SensorType::Radar { bias, .. } = self.spec.model else {
            return ([0.0; 2], [0.0; 2]);
        };
        match bias {
            BiasModel::None => ([0.0; 2], [0.0; 2]),
            BiasModel::Abrupt {
                t_on,
                t_off,
                scale,
                offset,
            } => {
                if t >= t_on && t < t_off {
                    (scale, offset)
                } else {
                    ([0.0; 2], [0.0; 2])
                }
            }
            BiasModel::Markov {
                mean,
                std,
                tau_s,
                scale,
            } => {
                let w: [f64; 2] = [
                    self.rng.sample(StandardNormal),
                    self.rng.sample(StandardNormal),
                ];
                let o = match self.markov {
                    // Stationary start.
                    None => [mean[0] + std[0] * w[0], mean[1] + std[1] * w[1]],
                    // Exact discretisation of do = −(o − m)/τ dt + σ √(2/τ) dW.
                    Some((o, t0)) => {
                        let a = (-(t - t0).max(0.0) / tau_s).exp();
                        let k = (1.0 - a * a).sqrt();
                        [
                            mean[0] + a * (o[0] - mean[0]) + std[0] * k * w[0],
                            mean[1] + a * (o[1] - mean[1]) + std[1] * k * w[1],
                        ]
                    }
                };
                self.markov = Some((o, t));
                (scale, o)
            }
        }
    }

    fn detect(
        &mut self,
        t: f64,
        pose: &PlatformPose,
        truths: &[Vector3<f64>],
        sizes: &[f64],
        plane_z: f64,
        gimbal: Option<Vector3<f64>>,
    ) -> (Vec<Detection>, Vec<Option<usize>>) {
        let sensor = Vector3::from(pose.pos);
        let b = self.boresight(pose, truths, gimbal);
        let cos_half = match &self.spec.model {
            SensorType::Camera { fov_deg, .. } => (0.5 * fov_deg.to_radians()).cos(),
            SensorType::Radar { .. } => -1.0,
        };
        let (scale, offset) = self.bias(t);
        let [m_az, m_el] = match &self.spec.model {
            SensorType::Camera { mounting_deg, .. } => mounting_deg.map(f64::to_radians),
            SensorType::Radar { .. } => [0.0, 0.0],
        };
        let std = &self.spec.noise_std;
        let mut found: Vec<(Detection, Option<usize>)> = Vec::new();
        for (i, p) in truths.iter().enumerate() {
            // Same draws every scan: detection, then three normals.
            let u: f64 = self.rng.random();
            let n: [f64; 3] = [
                self.rng.sample(StandardNormal),
                self.rng.sample(StandardNormal),
                self.rng.sample(StandardNormal),
            ];
            let d = p - sensor;
            let rho = d.norm();
            let visible = rho > 1e-6 && rho <= self.spec.max_range_m && d.dot(&b) >= cos_half * rho;
            if !visible || u >= self.spec.pd {
                continue;
            }
            let x = SVector::<f64, 6>::new(p.x, p.y, p.z, 0.0, 0.0, 0.0);
            let g = Geometry::spatial();
            let z = match self.kind {
                MeasKind::Position => vec![p.x + std[0] * n[0], p.y + std[1] * n[1]],
                MeasKind::RangeBearing => {
                    let h = RangeBearing::new(g, sensor, [std[0], std[1]]).function(&x);
                    vec![
                        ((1.0 + scale[0]) * h[0] + offset[0] + std[0] * n[0]).max(0.0),
                        wrap_angle((1.0 + scale[1]) * h[1] + offset[1] + std[1] * n[1]),
                    ]
                }
                MeasKind::AzEl => {
                    let h = AzEl::new(g, sensor, [std[0], std[1]]).function(&x);
                    vec![
                        wrap_angle(h[0] + m_az + std[0] * n[0]),
                        (h[1] + m_el + std[1] * n[1]).clamp(-FRAC_PI_2, FRAC_PI_2),
                    ]
                }
                MeasKind::BearingSize => {
                    let size = TargetSize::Known(sizes.get(i).copied().unwrap_or(1.0));
                    let h =
                        BearingSize::new(g, sensor, size, [std[0], std[1], std[2]]).function(&x);
                    vec![
                        wrap_angle(h[0] + m_az + std[0] * n[0]),
                        (h[1] + m_el + std[1] * n[1]).clamp(-FRAC_PI_2, FRAC_PI_2),
                        h[2] + std[2] * n[2],
                    ]
                }
            };
            if z.iter().all(|v| v.is_finite()) {
                found.push((Detection { z }, Some(i)));
            }
        }
        let clutter = self
            .poisson
            .map_or(0.0, |p| p.sample(&mut self.rng))
            .min(1e5) as usize;
        let mean_size = sizes.iter().sum::<f64>() / sizes.len().max(1) as f64;
        let half = cos_half.clamp(-1.0, 1.0).acos();
        for _ in 0..clutter {
            let z = match (&self.spec.model, self.kind) {
                (SensorType::Radar { .. }, _) => Some(vec![
                    self.rng.random_range(0.0..=self.spec.max_range_m),
                    self.rng.random_range(-PI..PI),
                ]),
                (_, MeasKind::Position) => {
                    let dir = in_cone(&mut self.rng, &b, half);
                    let lambda = (plane_z - sensor.z) / dir.z;
                    (dir.z < -1e-9 && lambda > 0.0 && lambda <= self.spec.max_range_m).then(|| {
                        let q = sensor + dir * lambda;
                        vec![q.x, q.y]
                    })
                }
                (_, MeasKind::BearingSize) => {
                    let dir = in_cone(&mut self.rng, &b, half);
                    let lo = mean_size.min(self.spec.max_range_m);
                    let rho = self.rng.random_range(lo..=self.spec.max_range_m);
                    let [az, el] = az_el_of(&dir);
                    Some(vec![az, el, 2.0 * (mean_size / (2.0 * rho)).atan()])
                }
                _ => Some(az_el_of(&in_cone(&mut self.rng, &b, half)).to_vec()),
            };
            if let Some(z) = z.filter(|z| z.iter().all(|v| v.is_finite())) {
                found.push((Detection { z }, None));
            }
        }
        found.shuffle(&mut self.rng);
        found.into_iter().unzip()
    }
}

#[cfg(test)]
mod tests;
