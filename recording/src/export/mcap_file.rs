//! A recorded session as an MCAP file ([`mcap`]) of the topics and Foxglove schemas the live
//! service's Foxglove feed publishes ([`crate::foxglove`]), for Foxglove, Lichtblick and the
//! `mcap` tools.
//!
//! What the file holds, each message logged at its time on the session's time line (the
//! tracker's: `time_unix` when every scan carries it, else the senders' `t`):
//!
//! | topic | one message per |
//! |---|---|
//! | `/harrier/detections` | `scans` row (its detections, in the session's frame) |
//! | `/harrier/vehicles/location`, `/tf` | `scans` row whose platform position is finite (the vehicle's pose at that scan) |
//! | `/harrier/tracks` | group of `tracks` rows one scan wrote (the tracks it changed) |
//! | `/harrier/tracks/location` | confirmed `tracks` row whose estimate is finite |
//!
//! Unlike the live scene, an exported track entity is not deleted when the track ends (the
//! recording does not keep track ends): it lasts
//! [`EXPORT_TRACK_LIFETIME_S`](crate::foxglove::EXPORT_TRACK_LIFETIME_S) past the last scan that
//! changed it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use foxglove::Context;
use foxglove::messages::{FrameTransforms, LocationFix, SceneUpdate};
use harrier_core::measurement::Geometry;
use harrier_engine::TrackView;
use harrier_link::detections::scan_in_frame;
use harrier_link::geo::LocalFrame;

use super::session::Recorded;
use super::times::TimeLine;
use crate::foxglove::{
    DETECTIONS, ScanLines, TF, TRACK_FIXES, TRACKS, VEHICLE_FIXES, VehiclePose,
    changed_tracks_update, detections_entity, timestamp, track_fix, vehicle_fix,
    vehicle_transforms,
};
use crate::reader::{Db, SessionError};

/// What [`mcap`] wrote.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct McapExported {
    /// Session id.
    pub session: i64,
    /// The file written.
    pub path: PathBuf,
    /// Messages written per topic.
    pub messages: BTreeMap<&'static str, u64>,
    /// `scans` rows read.
    pub scans: u64,
    /// `tracks` rows read.
    pub track_rows: u64,
    /// The time line of the log times: `time_unix` or `t`.
    pub time_line: String,
    /// Log time of the first and the last message (s on the time line).
    pub span: [f64; 2],
}

/// One message to log, at its time.
enum Item {
    Scan(usize),
    Tracks(std::ops::Range<usize>),
}

/// Writes session `id` of `db` into the MCAP file `out`, which must not exist: it is written
/// beside as `out` + `.partial` and renamed when complete, so `out` is whole or absent.
pub fn mcap(db: &Path, id: i64, out: &Path) -> Result<McapExported, SessionError> {
    let d = Db::open(db)?;
    let session = Recorded::read(&d, id)?;
    let tracks = d.tracks(id)?;
    let frame = LocalFrame::new(session.origin());
    let geometry = Geometry::planar(session.info.plane_z);
    let line = TimeLine::new(&session.scans);
    let fail = |message: String| SessionError::Mcap {
        path: out.to_path_buf(),
        message,
    };
    if out.exists() {
        return Err(fail("it exists (remove it first)".into()));
    }

    // Every message's time: a scan's on the time line, a group of track rows' its `t`.
    let mut items: Vec<(f64, Item)> = Vec::new();
    for (i, (row, scan)) in session.scans.iter().enumerate() {
        let t = line.absolute(scan.t, scan.time_unix).ok_or_else(|| {
            d.export_error(id, format!("scans row {row} has no time on the time line"))
        })?;
        items.push((t, Item::Scan(i)));
    }
    let mut start = 0;
    while start < tracks.len() {
        let t = tracks[start].t;
        let end = start
            + tracks[start..]
                .iter()
                .take_while(|k| k.t.to_bits() == t.to_bits())
                .count();
        items.push((t, Item::Tracks(start..end)));
        start = end;
    }
    items.sort_by(|a, b| a.0.total_cmp(&b.0));

    let partial = PathBuf::from(format!("{}.partial", out.display()));
    let ctx = Context::new();
    let writer = ctx
        .mcap_writer()
        .create_new_buffered_file(&partial)
        .map_err(|e| fail(format!("cannot create {}: {e}", partial.display())))?;
    let scenes = ctx.channel_builder(TRACKS).build::<SceneUpdate>();
    let track_fixes = ctx.channel_builder(TRACK_FIXES).build::<LocationFix>();
    let detections = ctx.channel_builder(DETECTIONS).build::<SceneUpdate>();
    let vehicle_fixes = ctx.channel_builder(VEHICLE_FIXES).build::<LocationFix>();
    let tf = ctx.channel_builder(TF).build::<FrameTransforms>();
    let mut messages: BTreeMap<&'static str, u64> =
        [TRACKS, TRACK_FIXES, DETECTIONS, VEHICLE_FIXES, TF]
            .into_iter()
            .map(|t| (t, 0))
            .collect();
    let mut count = |topic: &'static str| *messages.entry(topic).or_default() += 1;
    for (t, item) in &items {
        let stamp = timestamp(*t);
        let nanos = nanos(*t);
        match item {
            Item::Scan(i) => {
                let (row, scan) = &session.scans[*i];
                let local = scan_in_frame(scan, &frame, geometry)
                    .map_err(|e| d.malformed(id, format!("scans row {row}: {e}")))?;
                let vehicle = scan.vehicle.to_string();
                let platform: [f64; 3] = local.platform_pos.into();
                let entity = detections_entity(
                    &ScanLines {
                        vehicle: &vehicle,
                        sensor: &scan.sensor,
                        kind: scan.kind,
                        platform,
                        detections: &local.detections,
                        plane_z: session.info.plane_z,
                    },
                    stamp,
                );
                detections.log_with_time(
                    &SceneUpdate {
                        deletions: Vec::new(),
                        entities: vec![entity],
                    },
                    nanos,
                );
                count(DETECTIONS);
                let pose = VehiclePose {
                    label: &vehicle,
                    position: platform,
                    geodetic: frame.from_enu(&local.platform_pos),
                };
                if let Some(fix) = vehicle_fix(&pose, stamp) {
                    vehicle_fixes.log_with_time(&fix, nanos);
                    count(VEHICLE_FIXES);
                }
                let transforms = vehicle_transforms(&[pose], stamp);
                if !transforms.transforms.is_empty() {
                    tf.log_with_time(&transforms, nanos);
                    count(TF);
                }
            }
            Item::Tracks(range) => {
                let group: &[TrackView] = &tracks[range.clone()];
                scenes.log_with_time(&changed_tracks_update(group, stamp), nanos);
                count(TRACKS);
                for fix in group.iter().filter_map(|k| track_fix(k, &frame, stamp)) {
                    track_fixes.log_with_time(&fix, nanos);
                    count(TRACK_FIXES);
                }
            }
        }
    }
    writer
        .close()
        .map_err(|e| fail(format!("cannot finish {}: {e}", partial.display())))?;
    std::fs::rename(&partial, out).map_err(|e| {
        let _ = std::fs::remove_file(&partial);
        fail(format!("cannot rename {}: {e}", partial.display()))
    })?;
    Ok(McapExported {
        session: id,
        path: out.to_path_buf(),
        messages,
        scans: session.scans.len() as u64,
        track_rows: tracks.len() as u64,
        time_line: line.name().into(),
        span: [
            items.first().map_or(0.0, |i| i.0),
            items.last().map_or(0.0, |i| i.0),
        ],
    })
}

/// A time on the time line as an MCAP log time (ns since the UNIX epoch; 0 before it or when
/// not finite).
fn nanos(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round().min(u64::MAX as f64) as u64
    } else {
        0
    }
}
