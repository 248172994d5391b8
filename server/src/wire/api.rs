//! The service's own messages: what the REST API, the WebSocket and the Zenoh tracks carry.

use harrier_core::detection::{GeoPoint, TRACKS_SCHEMA};
use harrier_core::measurement::MeasKind;
use harrier_core::tracker::{DeleteReason, TrackEvent};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::clock::ClockEstimate;
use crate::gcs::LinkEvent;
use crate::gcs::vehicle::VehicleLinkView;
use crate::guidance::AssignmentView;
use crate::tracker::{ScanEvents, Snapshot, TrackFilterState, VehicleView};
pub use harrier_engine::{CHI2_95_2, CHI2_95_3, Ellipse, Ellipsoid};
use harrier_engine::{SensorBiasView, TrackStatus, TrackView};

/// A track as the API sends it (REST, WebSocket, Zenoh): the engine's estimate with its 95 %
/// confidence regions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TrackDto {
    /// Stable track id.
    pub id: u64,
    /// `tentative` or `confirmed`.
    pub status: TrackStatus,
    /// Time of the estimate (s).
    pub t: f64,
    /// `[x, y, z, vx, vy, vz]` (ENU, m and m/s; planar: z = the ground plane, vz = 0).
    pub state: [f64; 6],
    /// Covariance over the state indices `cov_dims`.
    pub cov: Vec<Vec<f64>>,
    /// The state indices `cov` covers.
    pub cov_dims: Vec<usize>,
    /// Whether the last scan updated the track (`false`: it coasted).
    pub updated: bool,
    /// Scans since initiation.
    pub age: u32,
    /// Time of the last associated detection (s).
    pub last_update: f64,
    /// Mode probabilities of an IMM track (empty otherwise).
    pub mode_probabilities: Vec<f64>,
    /// Probability that the track follows a real target (the `jipda` and `mht` associators;
    /// `null` under `gnn`).
    pub existence: Option<f64>,
    /// 95 % position ellipse over (x, y); `null` when the covariance lacks them.
    pub ellipse_95: Option<Ellipse>,
    /// 95 % position ellipsoid over (x, y, z); `null` for planar tracks.
    pub ellipsoid_95: Option<Ellipsoid>,
}

impl From<&TrackView> for TrackDto {
    fn from(k: &TrackView) -> Self {
        Self {
            id: k.id,
            status: k.status,
            t: k.t,
            state: k.state,
            cov: k.cov.clone(),
            cov_dims: k.cov_dims.clone(),
            updated: k.updated,
            age: k.age,
            last_update: k.last_update,
            mode_probabilities: k.mode_probabilities.clone(),
            existence: k.existence,
            ellipse_95: Ellipse::of(k),
            ellipsoid_95: Ellipsoid::of(k),
        }
    }
}

/// A measurement kind (FORMAT.md §3) as the API sends harrier-core's `MeasKind`: that type's
/// OpenAPI schema (component `MeasKind`), which harrier-core, without OpenAPI, does not derive.
/// Fields of type `MeasKind` name it with `#[schema(value_type = MeasKindSchema)]`; the
/// exhaustive [`From`] keeps the two alike.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = MeasKind)]
pub enum MeasKindSchema {
    /// Absolute ENU position `[x, y]` or `[x, y, z]`.
    Position,
    /// `[range, azimuth]`.
    RangeBearing,
    /// `[azimuth, elevation]`.
    AzEl,
    /// `[azimuth, elevation, subtended]`.
    BearingSize,
}

impl From<MeasKind> for MeasKindSchema {
    fn from(k: MeasKind) -> Self {
        match k {
            MeasKind::Position => Self::Position,
            MeasKind::RangeBearing => Self::RangeBearing,
            MeasKind::AzEl => Self::AzEl,
            MeasKind::BearingSize => Self::BearingSize,
        }
    }
}

/// Why a track was deleted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum DeleteCause {
    /// A confirmed track missed too many consecutive scans.
    Misses,
    /// Its position uncertainty grew past the bound.
    Covariance,
    /// A tentative track can no longer meet the M-of-N rule.
    Unconfirmed,
    /// Its filter failed (`message` says why).
    Failed,
}

/// What one scan did to one track (the `events` of a `scan` message).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum TrackEventDto {
    /// A tentative track was started from detection `detection` of the scan.
    Born {
        /// New track id.
        id: u64,
        /// Index of the detection in the scan.
        detection: usize,
    },
    /// A tentative track met the M-of-N rule.
    Confirmed {
        /// Track id.
        id: u64,
    },
    /// A track was updated with detection `detection`.
    Updated {
        /// Track id.
        id: u64,
        /// Index of the detection in the scan.
        detection: usize,
        /// Normalised innovation squared of the detection (`null` when not finite).
        nis: Option<f64>,
    },
    /// A track had no detection in this scan.
    Coasted {
        /// Track id.
        id: u64,
        /// Consecutive misses, this scan included.
        misses: u32,
    },
    /// A track was deleted.
    Deleted {
        /// Track id.
        id: u64,
        /// Why.
        reason: DeleteCause,
        /// The filter's error (`failed`), else `null`.
        message: Option<String>,
    },
    /// Something of this scan could not be used (a track's update, or a detection starting one).
    Rejected {
        /// The track concerned, if any.
        id: Option<u64>,
        /// The detection concerned, if any.
        detection: Option<usize>,
        /// Why.
        reason: String,
    },
}

impl From<&TrackEvent> for TrackEventDto {
    fn from(e: &TrackEvent) -> Self {
        match e {
            &TrackEvent::Born { id, detection } => Self::Born { id, detection },
            &TrackEvent::Confirmed { id } => Self::Confirmed { id },
            &TrackEvent::Updated { id, detection, nis } => Self::Updated {
                id,
                detection,
                nis: nis.is_finite().then_some(nis),
            },
            &TrackEvent::Coasted { id, misses } => Self::Coasted { id, misses },
            TrackEvent::Deleted { id, reason } => {
                let (reason, message) = match reason {
                    DeleteReason::Misses => (DeleteCause::Misses, None),
                    DeleteReason::Covariance => (DeleteCause::Covariance, None),
                    DeleteReason::Unconfirmed => (DeleteCause::Unconfirmed, None),
                    DeleteReason::Failed(m) => (DeleteCause::Failed, Some(m.clone())),
                };
                Self::Deleted {
                    id: *id,
                    reason,
                    message,
                }
            }
            TrackEvent::Rejected {
                id,
                detection,
                reason,
            } => Self::Rejected {
                id: *id,
                detection: *detection,
                reason: reason.clone(),
            },
        }
    }
}

/// A vehicle: its MAVLink link (when the GCS link hears it) and its detections (when it
/// publishes any), joined on the system id. The one shape of a vehicle on the API and the
/// WebSocket.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct VehicleEntry {
    /// MAVLink system id (the `{id}` of `harrier/v1/vehicle/{id}/detections`).
    pub id: u8,
    /// Telemetry and link state; `null` when the GCS link has not heard it.
    pub link: Option<VehicleLinkView>,
    /// Its detections; `null` when none was processed.
    pub detections: Option<VehicleView>,
    /// Its clock as estimated from its scans' `time_unix` (`[clock]`); `null` before the first
    /// stamped scan.
    pub clock: Option<ClockEstimate>,
    /// Its scans refused because their `time_unix` was outside the bound (drop reason `clock`).
    pub clock_refused: u64,
}

impl VehicleEntry {
    /// Vehicle `id`, known from nothing yet.
    pub fn new(id: u8) -> Self {
        Self {
            id,
            link: None,
            detections: None,
            clock: None,
            clock_refused: 0,
        }
    }
}

/// The `snapshot` message: the whole state, on connect and after the client fell behind.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct SnapshotMessage {
    /// Scans processed so far.
    pub seq: u64,
    /// Time of the last processed scan.
    pub t: Option<f64>,
    /// Every live track (tentative too), in id order.
    pub tracks: Vec<TrackDto>,
    /// Every vehicle, by system id.
    pub vehicles: Vec<VehicleEntry>,
    /// The track filter running.
    pub estimator: TrackFilterState,
    /// Scan messages this client missed since the last snapshot (0 on connect).
    pub dropped: u64,
}

impl SnapshotMessage {
    /// The message of `s` with `vehicles`, after `dropped` lost scan messages.
    pub fn new(s: &Snapshot, vehicles: Vec<VehicleEntry>, dropped: u64) -> Self {
        Self {
            seq: s.seq,
            t: s.t,
            tracks: s.tracks.iter().map(TrackDto::from).collect(),
            vehicles,
            estimator: (*s.estimator).clone(),
            dropped,
        }
    }
}

/// The `scan` message: one processed scan, what it held and what it did to the tracks.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ScanMessage {
    /// Processed-scan counter, from 1: consecutive unless the client was dropped to a snapshot.
    pub seq: u64,
    /// Scan time.
    pub t: f64,
    /// Vehicle label.
    pub vehicle: String,
    /// Sensor id on the vehicle.
    pub sensor: String,
    /// Measurement kind (`position`, `range_bearing`, `az_el`, `bearing_size`).
    #[schema(value_type = MeasKindSchema)]
    pub kind: MeasKind,
    /// Sensor (platform) position (ENU, m).
    pub platform: [f64; 3],
    /// The detections (FORMAT.md §3 layout of `kind`, server frame).
    pub detections: Vec<Vec<f64>>,
    /// What happened to the tracks.
    pub events: Vec<TrackEventDto>,
    /// The tracks the scan started, confirmed or updated (a deleted track has a `deleted`
    /// event; a coasted one keeps its last state).
    pub tracks: Vec<TrackDto>,
    /// The registered sensors' bias estimates, in the scans that refreshed them (sensor
    /// registration, at most 2 Hz); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub biases: Option<Vec<SensorBiasView>>,
}

impl From<&ScanEvents> for ScanMessage {
    fn from(s: &ScanEvents) -> Self {
        Self {
            seq: s.seq,
            t: s.t,
            vehicle: s.vehicle.clone(),
            sensor: s.sensor.clone(),
            kind: s.kind,
            platform: s.platform,
            detections: s.detections.clone(),
            events: s.events.iter().map(TrackEventDto::from).collect(),
            tracks: s.changed_tracks().map(TrackDto::from).collect(),
            biases: s.biases.as_ref().map(|b| b.to_vec()),
        }
    }
}

/// The `vehicles` message (10 Hz while the MAVLink link runs): as `GET /api/v1/vehicles` and
/// `GET /api/v1/assignments`.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct VehiclesMessage {
    /// Every vehicle, by system id.
    pub vehicles: Vec<VehicleEntry>,
    /// Every assignment.
    pub assignments: Vec<AssignmentView>,
}

/// One WebSocket text frame (`GET /api/v1/ws`), told apart by `type`.
#[derive(Debug, Clone, Serialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum WsMessage {
    /// The whole state (`{"type": "snapshot", …}`).
    Snapshot(SnapshotMessage),
    /// One processed scan (`{"type": "scan", …}`).
    Scan(ScanMessage),
    /// The vehicles and assignments (`{"type": "vehicles", …}`).
    Vehicles(VehiclesMessage),
    /// A vehicle's link or flight state changed.
    VehicleEvent {
        /// What happened.
        event: LinkEvent,
    },
    /// An assignment was created, a vehicle of it changed state, or it ended.
    Assignment {
        /// The assignment after the change.
        assignment: AssignmentView,
    },
}

/// `m` as JSON text. Serialising a message cannot fail (only a map with non-string keys does,
/// and none has one); if it did, the error is logged and `{}` sent.
pub fn to_json<T: Serialize>(m: &T) -> String {
    serde_json::to_string(m).unwrap_or_else(|e| {
        tracing::error!("serialising a message: {e}");
        String::from("{}")
    })
}

/// The `scan` message of `s`, serialised once for every client.
pub fn scan_json(s: &ScanEvents) -> &str {
    s.wire_cache()
        .get_or_init(|| to_json(&WsMessage::Scan(ScanMessage::from(s))))
}

/// The frame of a [`TracksMessage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TracksFrame {
    /// Origin of the server's ENU frame (WGS-84: `lat_deg`, `lon_deg`, `alt_m`).
    #[schema(value_type = Object)]
    pub origin: GeoPoint,
    /// Up coordinate (m) of the ground plane.
    pub plane_z: f64,
}

/// The Zenoh tracks message, schema `harrier-tracks/1` (DETECTIONS.md §Tracks): a ground
/// station's confirmed tracks in its ENU frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TracksMessage {
    /// `harrier-tracks/1`.
    pub schema: String,
    /// Wall-clock time of publication (UNIX s).
    pub time_unix: f64,
    /// Time of the last processed scan.
    pub t: Option<f64>,
    /// Scans processed so far.
    pub seq: u64,
    /// The track filter running.
    pub estimator: String,
    /// The frame of the positions.
    pub frame: TracksFrame,
    /// The confirmed tracks, in id order.
    pub tracks: Vec<TrackDto>,
}

impl TracksMessage {
    /// The message of `snap`'s confirmed tracks, published at `time_unix`.
    pub fn new(snap: &Snapshot, frame: TracksFrame, time_unix: f64) -> Self {
        Self {
            schema: TRACKS_SCHEMA.to_string(),
            time_unix,
            t: snap.t,
            seq: snap.seq,
            estimator: snap.estimator.name.clone(),
            frame,
            tracks: snap
                .tracks
                .iter()
                .filter(|k| k.status == TrackStatus::Confirmed)
                .map(TrackDto::from)
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;
    use std::sync::Arc;

    use serde_json::json;

    use super::*;
    use crate::config::DEFAULT_ORIGIN;

    /// A planar track with covariance diag(4, 1) over (x, y) and (4, 1) over (vx, vy).
    fn planar(id: u64, status: TrackStatus) -> TrackView {
        TrackView {
            id,
            status,
            t: 10.0,
            state: [100.0, 50.0, 0.0, 2.0, -1.0, 0.0],
            cov: vec![
                vec![4.0, 0.0, 0.0, 0.0],
                vec![0.0, 1.0, 0.0, 0.0],
                vec![0.0, 0.0, 4.0, 0.0],
                vec![0.0, 0.0, 0.0, 1.0],
            ],
            cov_dims: vec![0, 1, 3, 4],
            updated: true,
            age: 7,
            last_update: 10.0,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    /// The JSON of [`planar`]: what `TrackView` was on the wire, plus `ellipse_95` and
    /// `ellipsoid_95`.
    fn planar_json(id: u64, status: &str) -> serde_json::Value {
        let a = (4.0 * CHI2_95_2).sqrt();
        let b = CHI2_95_2.sqrt();
        json!({
            "id": id, "status": status, "t": 10.0, "state": [100.0, 50.0, 0.0, 2.0, -1.0, 0.0],
            "cov": [[4.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 4.0, 0.0],
                    [0.0, 0.0, 0.0, 1.0]],
            "cov_dims": [0, 1, 3, 4], "updated": true, "age": 7, "last_update": 10.0,
            "mode_probabilities": [],
            "existence": null,
            "ellipse_95": {"semi_axes": [a, b], "angle_rad": 0.0},
            "ellipsoid_95": null,
        })
    }

    #[test]
    fn a_scan_message_is_exactly_the_former_json_plus_the_ellipses() {
        let events = [
            TrackEvent::Born {
                id: 4,
                detection: 1,
            },
            TrackEvent::Confirmed { id: 3 },
            TrackEvent::Updated {
                id: 3,
                detection: 0,
                nis: 1.5,
            },
            TrackEvent::Updated {
                id: 5,
                detection: 2,
                nis: f64::NAN,
            },
            TrackEvent::Coasted { id: 2, misses: 2 },
            TrackEvent::Deleted {
                id: 1,
                reason: DeleteReason::Misses,
            },
            TrackEvent::Deleted {
                id: 6,
                reason: DeleteReason::Failed("not finite".into()),
            },
            TrackEvent::Rejected {
                id: None,
                detection: Some(3),
                reason: "outside".into(),
            },
        ];
        let m = WsMessage::Scan(ScanMessage {
            seq: 12,
            t: 10.0,
            vehicle: "2".into(),
            sensor: "cam".into(),
            kind: MeasKind::Position,
            platform: [0.0, 0.0, 120.0],
            detections: vec![vec![100.0, 50.0]],
            events: events.iter().map(TrackEventDto::from).collect(),
            tracks: vec![TrackDto::from(&planar(3, TrackStatus::Confirmed))],
            biases: None,
        });
        let got: serde_json::Value = serde_json::from_str(&to_json(&m)).expect("JSON");
        let want = json!({
            "type": "scan", "seq": 12, "t": 10.0, "vehicle": "2", "sensor": "cam",
            "kind": "position", "platform": [0.0, 0.0, 120.0], "detections": [[100.0, 50.0]],
            "events": [
                {"type": "born", "id": 4, "detection": 1},
                {"type": "confirmed", "id": 3},
                {"type": "updated", "id": 3, "detection": 0, "nis": 1.5},
                {"type": "updated", "id": 5, "detection": 2, "nis": null},
                {"type": "coasted", "id": 2, "misses": 2},
                {"type": "deleted", "id": 1, "reason": "misses", "message": null},
                {"type": "deleted", "id": 6, "reason": "failed", "message": "not finite"},
                {"type": "rejected", "id": null, "detection": 3, "reason": "outside"},
            ],
            "tracks": [planar_json(3, "confirmed")],
        });
        assert_eq!(got, want);
        // The events and tracks read back as they were.
        let back: Vec<TrackEventDto> =
            serde_json::from_value(want["events"].clone()).expect("events");
        let sent: Vec<TrackEventDto> = events.iter().map(TrackEventDto::from).collect();
        assert_eq!(back, sent);
        let k: TrackDto = serde_json::from_value(want["tracks"][0].clone()).expect("a track");
        assert_eq!(k, TrackDto::from(&planar(3, TrackStatus::Confirmed)));
    }

    #[test]
    fn a_tracks_message_is_exactly_the_former_json_plus_the_ellipses() {
        let snap = Snapshot {
            t: Some(10.0),
            seq: 12,
            tracks: Arc::new(vec![
                planar(3, TrackStatus::Confirmed),
                planar(4, TrackStatus::Tentative),
            ]),
            vehicles: Arc::new(Vec::new()),
            estimator: Arc::new(TrackFilterState {
                name: "ekf".into(),
                associator: "gnn".into(),
                params: BTreeMap::new(),
            }),
            biases: Arc::new(Vec::new()),
        };
        let frame = TracksFrame {
            origin: DEFAULT_ORIGIN,
            plane_z: 0.0,
        };
        let m = TracksMessage::new(&snap, frame, 1_700_000_000.5);
        let text = to_json(&m);
        let got: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        let origin = serde_json::to_value(DEFAULT_ORIGIN).expect("origin");
        let want = json!({
            "schema": "harrier-tracks/1", "time_unix": 1_700_000_000.5, "t": 10.0, "seq": 12,
            "estimator": "ekf", "frame": {"origin": origin, "plane_z": 0.0},
            "tracks": [planar_json(3, "confirmed")],
        });
        assert_eq!(got, want);
        let back: TracksMessage = serde_json::from_str(&text).expect("a round trip");
        assert_eq!(back, m);
    }

    #[test]
    fn the_other_messages_carry_their_type() {
        let snap = Snapshot {
            tracks: Arc::new(vec![planar(4, TrackStatus::Tentative)]),
            ..Snapshot::default()
        };
        let m = WsMessage::Snapshot(SnapshotMessage::new(&snap, vec![VehicleEntry::new(2)], 3));
        let got: serde_json::Value = serde_json::from_str(&to_json(&m)).expect("JSON");
        assert_eq!(
            got,
            json!({
                "type": "snapshot", "seq": 0, "t": null, "dropped": 3,
                "tracks": [planar_json(4, "tentative")],
                "vehicles": [{"id": 2, "link": null, "detections": null, "clock": null,
                              "clock_refused": 0}],
                "estimator": {"name": "", "associator": "", "params": {}},
            })
        );
        let m = WsMessage::Vehicles(VehiclesMessage {
            vehicles: Vec::new(),
            assignments: Vec::new(),
        });
        assert_eq!(
            to_json(&m),
            r#"{"type":"vehicles","vehicles":[],"assignments":[]}"#
        );
    }

    #[test]
    fn the_meas_kind_schema_names_what_a_meas_kind_sends() {
        for k in [
            MeasKind::Position,
            MeasKind::RangeBearing,
            MeasKind::AzEl,
            MeasKind::BearingSize,
        ] {
            let sent = serde_json::to_value(k).expect("a kind");
            assert_eq!(sent, json!(k.as_str()));
            assert_eq!(
                serde_json::to_value(MeasKindSchema::from(k)).ok(),
                Some(sent)
            );
        }
    }
}
