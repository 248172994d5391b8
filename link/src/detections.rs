//! Detection scans in a consumer's frame: a [`DetectionScan`] is expressed in the ENU frame of
//! its `origin`; a ground station (or a recording) tracks in its own ENU frame. [`scan_in_frame`]
//! re-expresses the platform and every detection there, and [`FrameScan::sensor_model`] builds
//! harrier-core's measurement model for it.
//!
//! Positions (the platform's, `position` detections) go exactly through ECEF (a 2-D `position`
//! fix is taken where the scan's vertical through it meets the consumer's target plane); velocities and
//! directions are rotated from the scan's axes into the consumer's ([`LocalFrame::rotation_to`]):
//! `az_el` and the angles of `bearing_size` through their unit line of sight, `range_bearing`'s
//! azimuth through the line of sight at the elevation the consumer's geometry implies (a planar
//! target at `plane_z`; level otherwise). Ranges and subtended angles do not depend on the frame.
//! When both frames have the same origin the scan is returned unchanged, bit for bit.

use harrier_core::detection::DetectionScan;
use harrier_core::linalg::wrap_angle;
use harrier_core::measurement::{Geometry, MeasKind, SensorModel, TargetSize};
use nalgebra::{Matrix3, Vector3};

use crate::geo::LocalFrame;

/// A scan expressed in a consumer's ENU frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameScan {
    /// Scan time (s).
    pub t: f64,
    /// Vehicle (MAVLink system id).
    pub vehicle: u8,
    /// Sensor id on the vehicle.
    pub sensor: String,
    /// Measurement kind.
    pub kind: MeasKind,
    /// Platform position (ENU, m) in the consumer's frame.
    pub platform_pos: Vector3<f64>,
    /// Platform velocity (ENU, m/s) in the consumer's axes.
    pub platform_vel: Vector3<f64>,
    /// Per-component noise std, as published.
    pub noise_std: Vec<f64>,
    /// Every detection's `z` in the consumer's frame (FORMAT.md §3 layout of `kind`).
    pub detections: Vec<Vec<f64>>,
    /// Where the target sits in the consumer's state (planar at `plane_z`, or 3-D).
    pub geometry: Geometry,
}

/// Why a scan cannot be used in a frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScanError {
    /// A detection has the wrong number of components for the scan's kind.
    #[error("detection {index} of a {kind:?} scan has {got} components")]
    Components {
        /// Index of the detection.
        index: usize,
        /// The scan's kind.
        kind: MeasKind,
        /// Its number of components.
        got: usize,
    },
    /// The measurement model cannot be built (noise, size, platform position).
    #[error("sensor model: {0}")]
    Model(String),
}

/// Unit line of sight of azimuth `az` (clockwise from North) and elevation `el`.
fn line_of_sight(az: f64, el: f64) -> Vector3<f64> {
    let (se, ce) = el.sin_cos();
    let (sa, ca) = az.sin_cos();
    Vector3::new(ce * sa, ce * ca, se)
}

/// Azimuth (clockwise from North, `[-π, π)`) and elevation of a direction.
fn angles(d: &Vector3<f64>) -> (f64, f64) {
    (wrap_angle(d.x.atan2(d.y)), d.z.atan2(d.x.hypot(d.y)))
}

/// `scan` in the ENU frame `frame`, for targets placed as `geometry` says.
pub fn scan_in_frame(
    scan: &DetectionScan,
    frame: &LocalFrame,
    geometry: Geometry,
) -> Result<FrameScan, ScanError> {
    let source = LocalFrame::new(scan.origin);
    let same = source.origin() == frame.origin();
    let pos = Vector3::from(scan.platform.pos);
    let platform_pos = source.enu_to_frame(frame, &pos);
    let rot: Matrix3<f64> = source.rotation_to(frame);
    let platform_vel = rot * Vector3::from(scan.platform.vel);
    let mut detections = Vec::with_capacity(scan.detections.len());
    for (index, d) in scan.detections.iter().enumerate() {
        let z = &d.z;
        let wrong = || ScanError::Components {
            index,
            kind: scan.kind,
            got: z.len(),
        };
        let ok = match scan.kind {
            MeasKind::Position => matches!(z.len(), 2 | 3),
            MeasKind::RangeBearing | MeasKind::AzEl => z.len() == 2,
            MeasKind::BearingSize => z.len() == 3,
        };
        if !ok {
            return Err(wrong());
        }
        if same {
            detections.push(z.clone());
            continue;
        }
        let out = match scan.kind {
            MeasKind::Position => {
                let at = |up: f64| source.enu_to_frame(frame, &Vector3::new(z[0], z[1], up));
                let up = match z.get(2) {
                    Some(&up) => up,
                    // A 2-D fix lies on the consumer's target plane: the height on the scan's
                    // vertical through (x, y) that lands there (the map is affine).
                    None if !geometry.up_in_state => {
                        let (z0, z1) = (at(0.0).z, at(1.0).z);
                        (geometry.plane_z - z0) / (z1 - z0)
                    }
                    None => 0.0,
                };
                let p = at(up);
                p.as_slice()[..z.len()].to_vec()
            }
            MeasKind::RangeBearing => {
                let el = if geometry.up_in_state || z[0] <= 0.0 {
                    0.0
                } else {
                    ((geometry.plane_z - platform_pos.z) / z[0])
                        .clamp(-1.0, 1.0)
                        .asin()
                };
                let (az, _) = angles(&(rot * line_of_sight(z[1], el)));
                vec![z[0], az]
            }
            MeasKind::AzEl | MeasKind::BearingSize => {
                let (az, el) = angles(&(rot * line_of_sight(z[0], z[1])));
                let mut v = vec![az, el];
                v.extend(z.get(2));
                v
            }
        };
        detections.push(out);
    }
    Ok(FrameScan {
        t: scan.t,
        vehicle: scan.vehicle,
        sensor: scan.sensor.clone(),
        kind: scan.kind,
        platform_pos,
        platform_vel,
        noise_std: scan.noise_std.clone(),
        detections,
        geometry,
    })
}

impl FrameScan {
    /// harrier-core's measurement model of the scan in the consumer's frame: its kind at the
    /// platform position with the published noise; `size` is the target size `bearing_size` needs.
    pub fn sensor_model(&self, size: Option<TargetSize>) -> Result<SensorModel, ScanError> {
        SensorModel::new(
            self.kind,
            self.geometry,
            self.platform_pos,
            &self.noise_std,
            size,
        )
        .map_err(ScanError::Model)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::detection::{DETECTIONS_SCHEMA, Detection, GeoPoint, PlatformPose};
    use harrier_core::measurement::MeasurementModel;
    use nalgebra::Vector4;

    const HOME: GeoPoint = GeoPoint {
        lat_deg: 47.397_742,
        lon_deg: 8.545_594,
        alt_m: 488.0,
    };

    fn scan(kind: MeasKind, pos: [f64; 3], z: Vec<f64>, noise_std: Vec<f64>) -> DetectionScan {
        let frame = LocalFrame::new(HOME);
        DetectionScan {
            time_unix: None,
            schema: DETECTIONS_SCHEMA.into(),
            t: 2.0,
            vehicle: 1,
            seq: 0,
            sensor: "s".into(),
            kind,
            origin: HOME,
            platform: PlatformPose {
                pos,
                vel: [1.0, 2.0, 0.0],
                attitude: [0.0; 3],
                geodetic: Some(frame.from_enu(&Vector3::from(pos))),
            },
            noise_std,
            detections: vec![Detection { z }],
        }
    }

    /// The noise-free value of `kind` for a target at `target` (ENU of `frame`) seen from `pos`.
    fn h(kind: MeasKind, g: Geometry, pos: Vector3<f64>, target: Vector3<f64>) -> Vec<f64> {
        let std = match kind {
            MeasKind::BearingSize => vec![1.0; 3],
            _ => vec![1.0; 2],
        };
        let m = SensorModel::new(kind, g, pos, &std, Some(TargetSize::Known(4.0))).unwrap();
        let x = Vector4::new(target.x, target.y, 0.0, 0.0);
        match m {
            SensorModel::RangeBearing(m) => MeasurementModel::<4, 2>::function(&m, &x)
                .as_slice()
                .to_vec(),
            SensorModel::AzEl(m) => MeasurementModel::<4, 2>::function(&m, &x)
                .as_slice()
                .to_vec(),
            SensorModel::BearingSize(m) => MeasurementModel::<4, 3>::function(&m, &x)
                .as_slice()
                .to_vec(),
            SensorModel::Position2(_) => vec![target.x, target.y],
            SensorModel::Position3(_) => unreachable!(),
        }
    }

    #[test]
    fn the_same_origin_changes_nothing() {
        let s = scan(
            MeasKind::AzEl,
            [10.0, 20.0, 300.0],
            vec![0.3, -1.2],
            vec![0.01; 2],
        );
        let f = scan_in_frame(&s, &LocalFrame::new(HOME), Geometry::planar(0.0)).unwrap();
        assert_eq!(f.detections, vec![vec![0.3, -1.2]]);
        assert_eq!(f.platform_pos, Vector3::new(10.0, 20.0, 300.0));
        assert_eq!(f.platform_vel, Vector3::new(1.0, 2.0, 0.0));
    }

    /// A target on the ground, seen from a scan published 3 km away: every kind converted into
    /// the consumer's frame equals what the consumer's own model predicts there.
    #[test]
    fn every_kind_matches_the_consumers_model_in_another_frame() {
        let src = LocalFrame::new(HOME);
        let dst = LocalFrame::new(GeoPoint::new(47.42, 8.51, 450.0));
        let (pos, target) = (
            Vector3::new(500.0, -300.0, 350.0),
            Vector3::new(900.0, 200.0, 0.0),
        );
        // The target on the consumer's ground plane, and where the scan's frame sees it.
        let g = Geometry::planar(0.0);
        let t_dst = Vector3::new(target.x, target.y, 0.0);
        let t_src = dst.enu_to_frame(&src, &t_dst);
        let pos_dst = src.enu_to_frame(&dst, &pos);
        for (kind, tol) in [
            (MeasKind::AzEl, 1e-9),
            (MeasKind::BearingSize, 1e-9),
            (MeasKind::Position, 1e-6),
            (MeasKind::RangeBearing, 1e-6),
        ] {
            let g_src = Geometry::planar(t_src.z);
            let z_src = match kind {
                MeasKind::Position => vec![t_src.x, t_src.y],
                _ => h(kind, g_src, pos, t_src),
            };
            let std = vec![1.0; z_src.len()];
            let s = scan(kind, pos.into(), z_src, std);
            let f = scan_in_frame(&s, &dst, g).unwrap();
            assert!((f.platform_pos - pos_dst).norm() < 1e-6, "{kind:?}");
            let want = h(kind, g, pos_dst, t_dst);
            for (a, b) in f.detections[0].iter().zip(&want) {
                assert!(
                    (a - b).abs() < tol * (1.0 + b.abs()),
                    "{kind:?}: {a} vs {b}"
                );
            }
            let model = f.sensor_model(Some(TargetSize::Known(4.0))).unwrap();
            assert_eq!(model.kind(), kind);
        }
        // Velocities rotate: a horizontal speed keeps its norm.
        let s = scan(MeasKind::AzEl, pos.into(), vec![0.0, -1.0], vec![0.01; 2]);
        let f = scan_in_frame(&s, &dst, g).unwrap();
        assert!((f.platform_vel.norm() - 5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn malformed_scans_are_refused() {
        let s = scan(MeasKind::AzEl, [0.0; 3], vec![0.3], vec![0.01; 2]);
        let e = scan_in_frame(&s, &LocalFrame::new(HOME), Geometry::spatial()).unwrap_err();
        assert!(matches!(e, ScanError::Components { got: 1, .. }), "{e}");
        let s = scan(
            MeasKind::BearingSize,
            [0.0; 3],
            vec![0.1, 0.2, 0.01],
            vec![0.01; 3],
        );
        let f = scan_in_frame(&s, &LocalFrame::new(HOME), Geometry::spatial()).unwrap();
        assert!(
            f.sensor_model(None)
                .is_err_and(|e| e.to_string().contains("size"))
        );
    }
}
