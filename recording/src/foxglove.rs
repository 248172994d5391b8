//! Harrier's scene as Foxglove's well-known schemas (protobuf, the `foxglove` SDK's types), for
//! Foxglove's 3-D and Map panels (and Lichtblick's). Pure: the time is passed in. The live
//! service's `foxglove` feed logs these on its channels, and [`crate::export::mcap`] writes a
//! recorded session's into an MCAP file, on the same topics:
//!
//! | topic | schema | what |
//! |---|---|---|
//! | [`TRACKS`] | `foxglove.SceneUpdate` | the tracks: an ellipsoid entity `track/<id>` in frame [`FRAME`] — a sphere primitive scaled to the 95 % region (3-D: its ellipsoid; planar: its ellipse, 0.5 m thick), orange when confirmed, grey when tentative — with its velocity as an arrow (10 s of travel) and its name `T<id>` as text. Live, each update first deletes every entity, so a deleted track disappears; in an export, each update holds the tracks a scan changed and an entity lasts [`EXPORT_TRACK_LIFETIME_S`]. |
//! | [`TRACK_FIXES`] | `foxglove.LocationFix` | one message per confirmed track, `frame_id` `track/<id>`: WGS-84 position of the estimate, its ENU position covariance (m², row-major, `KNOWN`), heading (degrees from north) and ENU velocity |
//! | [`DETECTIONS`] | `foxglove.SceneUpdate` | one entity per scan, `detections/<vehicle>/<sensor>`, lasting [`DETECTION_LIFETIME_S`]: a line from the sensor platform to each detection (a position, or a range and bearing placed on the ground plane: to the point, with a cube there; an angle-only one: along its line of sight to the ground plane, else 3 km) |
//! | [`VEHICLE_FIXES`] | `foxglove.LocationFix` | one message per vehicle, `frame_id` `uav/<id>`, at its sensor platform's last position |
//! | [`TF`] | `foxglove.FrameTransforms` | [`FRAME`] → `uav/<id>`: each vehicle's position in the server's frame |
//!
//! [`FRAME`] is the server's ENU frame (x east, y north, z up, metres from `frame.origin`).

use foxglove::messages::{
    ArrowPrimitive, Color, CubePrimitive, Duration, FrameTransform, FrameTransforms, LinePrimitive,
    LocationFix, Point3, Pose, Quaternion, SceneEntity, SceneEntityDeletion, SceneUpdate,
    SpherePrimitive, TextPrimitive, Timestamp, Vector3 as FVector3,
    line_primitive::Type as LineType, location_fix::PositionCovarianceType,
    scene_entity_deletion::Type as DeletionType,
};
use harrier_core::measurement::MeasKind;
use harrier_engine::{Ellipse, Ellipsoid, TrackStatus, TrackView};
use harrier_link::geo::{Geodetic, LocalFrame};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// The frame id of the server's ENU frame.
pub const FRAME: &str = "enu";
/// The tracks' scene topic.
pub const TRACKS: &str = "/harrier/tracks";
/// The confirmed tracks' location fixes.
pub const TRACK_FIXES: &str = "/harrier/tracks/location";
/// The scans' detections as a scene.
pub const DETECTIONS: &str = "/harrier/detections";
/// The vehicles' location fixes.
pub const VEHICLE_FIXES: &str = "/harrier/vehicles/location";
/// The frame transforms.
pub const TF: &str = "/tf";

/// Seconds a scan's detections stay in the scene.
pub const DETECTION_LIFETIME_S: f64 = 2.0;
/// Seconds a track's entity stays in an exported scene after the last scan that changed it (the
/// recording keeps only the tracks each scan changed, not when a track ended).
pub const EXPORT_TRACK_LIFETIME_S: f64 = 5.0;
/// Length (m) of an angle-only detection's line of sight that does not meet the ground plane.
const RAY_M: f64 = 3000.0;

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
pub fn track_entity(
    track: &TrackView,
    stamp: Timestamp,
    lifetime: Option<Duration>,
) -> Option<SceneEntity> {
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
        lifetime,
        arrows,
        spheres,
        texts: vec![text],
        ..SceneEntity::default()
    })
}

/// Every track as one scene update that replaces the previous one (live).
pub fn scene_update(tracks: &[TrackView], stamp: Timestamp) -> SceneUpdate {
    SceneUpdate {
        deletions: vec![SceneEntityDeletion {
            timestamp: Some(stamp),
            r#type: DeletionType::All as i32,
            id: String::new(),
        }],
        entities: tracks
            .iter()
            .filter_map(|t| track_entity(t, stamp, None))
            .collect(),
    }
}

/// The tracks one scan changed, as a scene update that leaves the others, each entity lasting
/// [`EXPORT_TRACK_LIFETIME_S`] (an export: the recording holds no track ends).
pub fn changed_tracks_update<'a>(
    tracks: impl IntoIterator<Item = &'a TrackView>,
    stamp: Timestamp,
) -> SceneUpdate {
    let lifetime = Some(Duration::saturating_from_secs_f64(EXPORT_TRACK_LIFETIME_S));
    SceneUpdate {
        deletions: Vec::new(),
        entities: tracks
            .into_iter()
            .filter_map(|t| track_entity(t, stamp, lifetime))
            .collect(),
    }
}

/// A scan as the scene draws it (in the server's frame, FORMAT.md §3 layouts).
#[derive(Debug, Clone, Copy)]
pub struct ScanLines<'a> {
    /// Vehicle label.
    pub vehicle: &'a str,
    /// Sensor id on the vehicle.
    pub sensor: &'a str,
    /// Measurement kind.
    pub kind: MeasKind,
    /// Sensor platform position (ENU, m).
    pub platform: [f64; 3],
    /// The detections.
    pub detections: &'a [Vec<f64>],
    /// The ground plane's height (m): where a planar target sits.
    pub plane_z: f64,
}

/// Where the scene draws detection `z`: its point (position, range and bearing on the ground
/// plane; `true`) or the end of its line of sight (angle-only; `false`). `None` when a component
/// is missing or not finite.
fn detection_end(s: &ScanLines<'_>, z: &[f64]) -> Option<(Vector3<f64>, bool)> {
    let p = Vector3::from(s.platform);
    let end = match s.kind {
        MeasKind::Position => (
            Vector3::new(
                *z.first()?,
                *z.get(1)?,
                z.get(2).copied().unwrap_or(s.plane_z),
            ),
            true,
        ),
        MeasKind::RangeBearing => {
            let (r, az) = (*z.first()?, *z.get(1)?);
            // The range is 3-D; the target is put on the ground plane.
            let dz = p.z - s.plane_z;
            let h = (r * r - dz * dz).max(0.0).sqrt();
            (
                Vector3::new(p.x + h * az.sin(), p.y + h * az.cos(), s.plane_z),
                true,
            )
        }
        MeasKind::AzEl | MeasKind::BearingSize => {
            let (az, el) = (*z.first()?, *z.get(1)?);
            let dir = Vector3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin());
            let len = if dir.z < -1e-6 {
                ((p.z - s.plane_z) / -dir.z).min(3.0 * RAY_M)
            } else {
                RAY_M
            };
            (p + dir * len, false)
        }
    };
    (end.0.iter().all(|c| c.is_finite()) && p.iter().all(|c| c.is_finite())).then_some(end)
}

fn point(v: Vector3<f64>) -> Point3 {
    Point3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// A scan's detections as a scene entity lasting [`DETECTION_LIFETIME_S`]: a line from the
/// platform to each detection (with a 2 m cube at a point detection). Detections that cannot be
/// drawn (a missing or non-finite component) are left out.
pub fn detections_entity(s: &ScanLines<'_>, stamp: Timestamp) -> SceneEntity {
    let color = Color {
        r: 1.0,
        g: 0.77,
        b: 0.35,
        a: 0.8,
    };
    let ends: Vec<_> = s
        .detections
        .iter()
        .filter_map(|z| detection_end(s, z))
        .collect();
    let origin = Vector3::from(s.platform);
    let lines = (!ends.is_empty())
        .then(|| LinePrimitive {
            r#type: LineType::LineList as i32,
            pose: Some(pose(Vector3::zeros(), UnitQuaternion::identity())),
            thickness: 0.4,
            scale_invariant: false,
            points: ends
                .iter()
                .flat_map(|(end, _)| [point(origin), point(*end)])
                .collect(),
            color: Some(color),
            ..LinePrimitive::default()
        })
        .into_iter()
        .collect();
    let cubes = ends
        .iter()
        .filter(|(_, at_point)| *at_point)
        .map(|(end, _)| CubePrimitive {
            pose: Some(pose(*end, UnitQuaternion::identity())),
            size: Some(v3(Vector3::new(2.0, 2.0, 2.0))),
            color: Some(color),
        })
        .collect();
    SceneEntity {
        timestamp: Some(stamp),
        frame_id: FRAME.into(),
        id: format!("detections/{}/{}", s.vehicle, s.sensor),
        lifetime: Some(Duration::saturating_from_secs_f64(DETECTION_LIFETIME_S)),
        lines,
        cubes,
        ..SceneEntity::default()
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

/// A vehicle as the scene shows it: its sensor platform's last position.
#[derive(Debug, Clone, Copy)]
pub struct VehiclePose<'a> {
    /// Vehicle label (MAVLink system id).
    pub label: &'a str,
    /// Position (ENU, m, in the server's frame).
    pub position: [f64; 3],
    /// The same position in WGS-84.
    pub geodetic: Geodetic,
}

/// A vehicle's location fix, at its sensor platform's last position.
pub fn vehicle_fix(vehicle: &VehiclePose<'_>, stamp: Timestamp) -> Option<LocationFix> {
    let g = &vehicle.geodetic;
    if !(g.lat_deg.is_finite() && g.lon_deg.is_finite() && g.alt_m.is_finite()) {
        return None;
    }
    Some(LocationFix {
        timestamp: Some(stamp),
        frame_id: format!("uav/{}", vehicle.label),
        latitude: g.lat_deg,
        longitude: g.lon_deg,
        altitude: g.alt_m,
        position_covariance_type: PositionCovarianceType::Unknown as i32,
        ..LocationFix::default()
    })
}

/// [`FRAME`] → `uav/<id>` for every vehicle whose position is finite.
pub fn vehicle_transforms(vehicles: &[VehiclePose<'_>], stamp: Timestamp) -> FrameTransforms {
    FrameTransforms {
        transforms: vehicles
            .iter()
            .filter(|v| v.position.iter().all(|c| c.is_finite()))
            .map(|v| FrameTransform {
                timestamp: Some(stamp),
                parent_frame_id: FRAME.into(),
                child_frame_id: format!("uav/{}", v.label),
                translation: Some(v3(Vector3::from(v.position))),
                rotation: Some(quat(UnitQuaternion::identity())),
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::detection::GeoPoint;

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
            existence: None,
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
        let frame = LocalFrame::new(GeoPoint::new(47.397_742, 8.545_594, 488.0));
        // σx = 4 m, σy = 2 m: the 95 % ellipse's semi-axes are 4·2.448 and 2·2.448.
        let t = track(
            TrackStatus::Confirmed,
            [100.0, 200.0, 0.0, 3.0, 4.0, 0.0],
            diag(&[16.0, 4.0, 1.0, 1.0]),
            vec![0, 1, 3, 4],
        );
        let stamp = timestamp(1_764_000_000.5);
        let e = track_entity(&t, stamp, None).unwrap();
        assert_eq!(e.id, "track/7");
        assert_eq!(e.frame_id, FRAME);
        let s = e.spheres[0].size.unwrap();
        let k = harrier_engine::CHI2_95_2.sqrt();
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
        let e = track_entity(&t, stamp, None).unwrap();
        let s = e.spheres[0].size.unwrap();
        let k = harrier_engine::CHI2_95_3.sqrt();
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
            track_fix(
                &t,
                &LocalFrame::new(GeoPoint::new(47.397_742, 8.545_594, 488.0)),
                stamp
            )
            .is_none(),
            "tentative"
        );
        let nan = track(
            TrackStatus::Confirmed,
            [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0],
            Vec::new(),
            Vec::new(),
        );
        assert!(track_entity(&nan, stamp, None).is_none());
        let update = scene_update(&[t, nan], stamp);
        assert_eq!(update.entities.len(), 1);
        assert_eq!(update.deletions[0].r#type, DeletionType::All as i32);
    }

    #[test]
    fn detections_are_lines_from_the_platform_to_their_points_or_along_their_sight() {
        let stamp = timestamp(5.0);
        let platform = [0.0, 0.0, 100.0];
        // A point and a broken detection (NaN): one line, one cube.
        let dets = vec![vec![30.0, 40.0], vec![f64::NAN, 1.0]];
        let e = detections_entity(
            &ScanLines {
                vehicle: "2",
                sensor: "cam",
                kind: MeasKind::Position,
                platform,
                detections: &dets,
                plane_z: 0.0,
            },
            stamp,
        );
        assert_eq!(e.id, "detections/2/cam");
        assert_eq!(e.lines[0].points.len(), 2);
        assert_eq!(e.cubes.len(), 1);
        let p = e.cubes[0].pose.unwrap().position.unwrap();
        assert_eq!((p.x, p.y, p.z), (30.0, 40.0, 0.0));
        assert_eq!(e.lifetime.unwrap().sec(), 2);
        // Range 125 m from 100 m up, due east: 75 m east on the ground.
        let dets = vec![vec![125.0, std::f64::consts::FRAC_PI_2]];
        let e = detections_entity(
            &ScanLines {
                kind: MeasKind::RangeBearing,
                detections: &dets,
                vehicle: "1",
                sensor: "radar",
                platform,
                plane_z: 0.0,
            },
            stamp,
        );
        let p = e.cubes[0].pose.unwrap().position.unwrap();
        assert!((p.x - 75.0).abs() < 1e-9 && p.y.abs() < 1e-9 && p.z == 0.0);
        // 45° down, due north: meets the ground 100 m north; no cube at a line of sight.
        let dets = vec![vec![0.0, -std::f64::consts::FRAC_PI_4]];
        let e = detections_entity(
            &ScanLines {
                kind: MeasKind::AzEl,
                detections: &dets,
                vehicle: "1",
                sensor: "cam",
                platform,
                plane_z: 0.0,
            },
            stamp,
        );
        assert!(e.cubes.is_empty());
        let end = e.lines[0].points[1];
        assert!(end.x.abs() < 1e-9 && (end.y - 100.0).abs() < 1e-9 && end.z.abs() < 1e-9);
    }
}
