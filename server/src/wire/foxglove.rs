//! The tracks and the vehicles as Foxglove's well-known schemas (protobuf, the `foxglove`
//! SDK's types), for Foxglove's 3-D and Map panels (and Lichtblick's). Pure: the time is passed
//! in; [`crate::feeds`]' `foxglove` actor logs these on its channels.
//!
//! | topic | schema | what |
//! |---|---|---|
//! | `/harrier/tracks` | `foxglove.SceneUpdate` | every live track: an ellipsoid entity `track/<id>` in frame [`FRAME`] — a sphere primitive scaled to the 95 % region (3-D: its ellipsoid; planar: its ellipse, 0.5 m thick), orange when confirmed, grey when tentative — with its velocity as an arrow (10 s of travel) and its name `T<id>` as text. Each update first deletes every entity, so a deleted track disappears. |
//! | `/harrier/tracks/location` | `foxglove.LocationFix` | one message per confirmed track, `frame_id` `track/<id>`: WGS-84 position of the estimate, its ENU position covariance (m², row-major, `KNOWN`), heading (degrees from north) and ENU velocity |
//! | `/harrier/vehicles/location` | `foxglove.LocationFix` | one message per vehicle, `frame_id` `uav/<id>`, at its sensor platform's last position |
//! | `/tf` | `foxglove.FrameTransforms` | [`FRAME`] → `uav/<id>`: each vehicle's position in the server's frame |
//!
//! [`FRAME`] is the server's ENU frame (x east, y north, z up, metres from `frame.origin`).

use foxglove::messages::{
    ArrowPrimitive, Color, FrameTransform, FrameTransforms, LocationFix, Pose, Quaternion,
    SceneEntity, SceneEntityDeletion, SceneUpdate, SpherePrimitive, TextPrimitive, Timestamp,
    Vector3 as FVector3, location_fix::PositionCovarianceType,
    scene_entity_deletion::Type as DeletionType,
};
use harrier_link::geo::LocalFrame;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use super::api::{Ellipse, Ellipsoid};
use crate::tracker::VehicleView;
use harrier_engine::{TrackStatus, TrackView};

/// The frame id of the server's ENU frame.
pub const FRAME: &str = "enu";

/// Seconds of travel the velocity arrow shows.
const ARROW_S: f64 = 10.0;

/// A UNIX time as Foxglove's timestamp (saturating outside its range, 0 when not finite).
pub fn timestamp(unix_s: f64) -> Timestamp {
    Timestamp::saturating_from_epoch_secs_f64(if unix_s.is_finite() { unix_s } else { 0.0 })
}

fn v3(v: Vector3<f64>) -> FVector3 {
    FVector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

fn quat(q: UnitQuaternion<f64>) -> Quaternion {
    Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

fn pose(position: Vector3<f64>, orientation: UnitQuaternion<f64>) -> Pose {
    Pose {
        position: Some(v3(position)),
        orientation: Some(quat(orientation)),
    }
}

fn finite(track: &TrackView) -> bool {
    track.state.iter().all(|v| v.is_finite())
}

/// The 95 % region of a track as a sphere primitive's size (diameters) and orientation: its
/// ellipsoid when the covariance covers z, else its ellipse, 0.5 m thick.
fn region(track: &TrackView) -> Option<(Vector3<f64>, UnitQuaternion<f64>)> {
    if let Some(e) = Ellipsoid::of(track) {
        let [a, b, c] = e.axes.map(Vector3::from);
        // A right-handed basis (the third axis' sign is free).
        let c = if a.cross(&b).dot(&c) < 0.0 { -c } else { c };
        let r = Rotation3::from_matrix(&Matrix3::from_columns(&[a, b, c]));
        let [sa, sb, sc] = e.semi_axes;
        return Some((Vector3::new(2.0 * sa, 2.0 * sb, 2.0 * sc), r.into()));
    }
    let e = Ellipse::of(track)?;
    let [sa, sb] = e.semi_axes;
    Some((
        Vector3::new(2.0 * sa, 2.0 * sb, 0.5),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), e.angle_rad),
    ))
}

/// A track's scene entity: its 95 % region, velocity arrow and name (`None` when the estimate is
/// not finite).
pub fn track_entity(track: &TrackView, stamp: Timestamp) -> Option<SceneEntity> {
    if !finite(track) {
        return None;
    }
    let [x, y, z, vx, vy, vz] = track.state;
    let p = Vector3::new(x, y, z);
    let v = Vector3::new(vx, vy, vz);
    let confirmed = track.status == TrackStatus::Confirmed;
    let color = if confirmed {
        Color {
            r: 1.0,
            g: 0.55,
            b: 0.1,
            a: 0.45,
        }
    } else {
        Color {
            r: 0.7,
            g: 0.7,
            b: 0.7,
            a: 0.3,
        }
    };
    let spheres = region(track)
        .filter(|(size, _)| size.iter().all(|s| s.is_finite()))
        .map(|(size, orientation)| SpherePrimitive {
            pose: Some(pose(p, orientation)),
            size: Some(v3(size)),
            color: Some(color),
        })
        .into_iter()
        .collect();
    let speed = v.norm();
    let arrows = (speed > 1e-3)
        .then(|| {
            // The arrow points along +x of its pose: turn +x onto the velocity.
            let orientation =
                UnitQuaternion::rotation_between(&Vector3::x(), &v).unwrap_or_else(|| {
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI)
                });
            let length = speed * ARROW_S;
            ArrowPrimitive {
                pose: Some(pose(p, orientation)),
                shaft_length: length * 0.8,
                shaft_diameter: 0.6,
                head_length: length * 0.2,
                head_diameter: 1.8,
                color: Some(Color { a: 0.9, ..color }),
            }
        })
        .into_iter()
        .collect();
    let text = TextPrimitive {
        pose: Some(pose(
            p + Vector3::new(0.0, 0.0, 3.0),
            UnitQuaternion::identity(),
        )),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: Some(Color {
            r: 1.0,
            g: 1.0,
            b: 1.0,
            a: 1.0,
        }),
        text: format!("T{}", track.id),
    };
    Some(SceneEntity {
        timestamp: Some(stamp),
        frame_id: FRAME.into(),
        id: format!("track/{}", track.id),
        arrows,
        spheres,
        texts: vec![text],
        ..SceneEntity::default()
    })
}

/// Every track as one scene update that replaces the previous one.
pub fn scene_update(tracks: &[TrackView], stamp: Timestamp) -> SceneUpdate {
    SceneUpdate {
        deletions: vec![SceneEntityDeletion {
            timestamp: Some(stamp),
            r#type: DeletionType::All as i32,
            id: String::new(),
        }],
        entities: tracks
            .iter()
            .filter_map(|t| track_entity(t, stamp))
            .collect(),
    }
}

/// A confirmed track's location fix (`None` for a tentative track or one not finite).
pub fn track_fix(track: &TrackView, frame: &LocalFrame, stamp: Timestamp) -> Option<LocationFix> {
    if track.status != TrackStatus::Confirmed || !finite(track) {
        return None;
    }
    let [x, y, z, vx, vy, vz] = track.state;
    let geo = frame.from_enu(&Vector3::new(x, y, z));
    if !(geo.lat_deg.is_finite() && geo.lon_deg.is_finite() && geo.alt_m.is_finite()) {
        return None;
    }
    // The ENU position covariance, row-major; a planar track's z variance is unknown (0). An
    // entry the covariance covers but that is not finite makes it unknown.
    let mut cov = [0.0; 9];
    let mut known = true;
    for i in 0..3 {
        for j in 0..3 {
            if track.cov_dims.contains(&i) && track.cov_dims.contains(&j) {
                match track.cov_at(i, j) {
                    Some(c) => cov[3 * i + j] = c,
                    None => known = false,
                }
            }
        }
    }
    Some(LocationFix {
        timestamp: Some(stamp),
        frame_id: format!("track/{}", track.id),
        latitude: geo.lat_deg,
        longitude: geo.lon_deg,
        altitude: geo.alt_m,
        position_covariance: if known { cov.to_vec() } else { Vec::new() },
        position_covariance_type: if known {
            PositionCovarianceType::Known
        } else {
            PositionCovarianceType::Unknown
        } as i32,
        heading: Some(vx.atan2(vy).to_degrees().rem_euclid(360.0)),
        velocity: Some(v3(Vector3::new(vx, vy, vz))),
        ..LocationFix::default()
    })
}

/// A vehicle's location fix, at its sensor platform's last position.
pub fn vehicle_fix(vehicle: &VehicleView, stamp: Timestamp) -> Option<LocationFix> {
    let g = &vehicle.geodetic;
    if !(g.lat_deg.is_finite() && g.lon_deg.is_finite() && g.alt_m.is_finite()) {
        return None;
    }
    Some(LocationFix {
        timestamp: Some(stamp),
        frame_id: format!("uav/{}", vehicle.vehicle),
        latitude: g.lat_deg,
        longitude: g.lon_deg,
        altitude: g.alt_m,
        position_covariance_type: PositionCovarianceType::Unknown as i32,
        ..LocationFix::default()
    })
}

/// [`FRAME`] → `uav/<id>` for every vehicle whose position is finite.
pub fn vehicle_transforms(vehicles: &[VehicleView], stamp: Timestamp) -> FrameTransforms {
    FrameTransforms {
        transforms: vehicles
            .iter()
            .filter(|v| v.position.iter().all(|c| c.is_finite()))
            .map(|v| FrameTransform {
                timestamp: Some(stamp),
                parent_frame_id: FRAME.into(),
                child_frame_id: format!("uav/{}", v.vehicle),
                translation: Some(v3(Vector3::from(v.position))),
                rotation: Some(quat(UnitQuaternion::identity())),
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;

    fn track(
        status: TrackStatus,
        state: [f64; 6],
        cov: Vec<Vec<f64>>,
        dims: Vec<usize>,
    ) -> TrackView {
        TrackView {
            id: 7,
            status,
            t: 10.0,
            state,
            cov,
            cov_dims: dims,
            updated: true,
            age: 5,
            last_update: 10.0,
            mode_probabilities: Vec::new(),
        }
    }

    fn diag(v: &[f64]) -> Vec<Vec<f64>> {
        (0..v.len())
            .map(|i| {
                (0..v.len())
                    .map(|j| if i == j { v[i] } else { 0.0 })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn a_planar_track_is_an_ellipse_an_arrow_and_a_fix() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        // σx = 4 m, σy = 2 m: the 95 % ellipse's semi-axes are 4·2.448 and 2·2.448.
        let t = track(
            TrackStatus::Confirmed,
            [100.0, 200.0, 0.0, 3.0, 4.0, 0.0],
            diag(&[16.0, 4.0, 1.0, 1.0]),
            vec![0, 1, 3, 4],
        );
        let stamp = timestamp(1_764_000_000.5);
        let e = track_entity(&t, stamp).unwrap();
        assert_eq!(e.id, "track/7");
        assert_eq!(e.frame_id, FRAME);
        let s = e.spheres[0].size.unwrap();
        let k = super::super::api::CHI2_95_2.sqrt();
        assert!(
            (s.x - 8.0 * k).abs() < 1e-9 && (s.y - 4.0 * k).abs() < 1e-9,
            "{s:?}"
        );
        let a = &e.arrows[0];
        assert!((a.shaft_length + a.head_length - 50.0).abs() < 1e-9);
        // +x of the arrow's pose is the velocity's direction.
        let o = a.pose.unwrap().orientation.unwrap();
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(o.w, o.x, o.y, o.z));
        let dir = q * Vector3::x();
        assert!((dir - Vector3::new(0.6, 0.8, 0.0)).norm() < 1e-9, "{dir}");
        assert_eq!(e.texts[0].text, "T7");

        let f = track_fix(&t, &frame, stamp).unwrap();
        let back = frame.to_enu(&harrier_link::geo::Geodetic {
            lat_deg: f.latitude,
            lon_deg: f.longitude,
            alt_m: f.altitude,
        });
        assert!((back - Vector3::new(100.0, 200.0, 0.0)).norm() < 1e-6);
        assert_eq!(f.position_covariance[0], 16.0);
        assert_eq!(f.position_covariance[4], 4.0);
        assert_eq!(f.position_covariance[8], 0.0);
        assert!((f.heading.unwrap() - 36.869_897_645_844_02).abs() < 1e-9);
    }

    #[test]
    fn a_3d_ellipsoid_keeps_its_axes_and_broken_tracks_are_left_out() {
        let t = track(
            TrackStatus::Tentative,
            [0.0; 6],
            diag(&[1.0, 9.0, 4.0, 1.0, 1.0, 1.0]),
            vec![0, 1, 2, 3, 4, 5],
        );
        let stamp = timestamp(0.0);
        let e = track_entity(&t, stamp).unwrap();
        let s = e.spheres[0].size.unwrap();
        let k = super::super::api::CHI2_95_3.sqrt();
        // Largest first: y (σ 3), z (σ 2), x (σ 1).
        assert!(
            (s.x - 6.0 * k).abs() < 1e-9
                && (s.y - 4.0 * k).abs() < 1e-9
                && (s.z - 2.0 * k).abs() < 1e-9
        );
        let o = e.spheres[0].pose.unwrap().orientation.unwrap();
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(o.w, o.x, o.y, o.z));
        assert!(
            (q * Vector3::x()).y.abs() > 1.0 - 1e-9,
            "the first axis is y"
        );
        assert!(e.arrows.is_empty(), "no arrow when standing");
        assert!(
            track_fix(&t, &LocalFrame::new(DEFAULT_ORIGIN), stamp).is_none(),
            "tentative"
        );
        let nan = track(
            TrackStatus::Confirmed,
            [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0],
            Vec::new(),
            Vec::new(),
        );
        assert!(track_entity(&nan, stamp).is_none());
        let update = scene_update(&[t, nan], stamp);
        assert_eq!(update.entities.len(), 1);
        assert_eq!(update.deletions[0].r#type, DeletionType::All as i32);
    }
}
