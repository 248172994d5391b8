//! Cursor-on-Target (CoT) events of the confirmed tracks, for TAK (ATAK, WinTAK, iTAK, TAK
//! Server): the CoT event schema 2.0 as XML (MITRE "Cursor-on-Target Message Router User's
//! Guide", event/point/detail, `version="2.0"`), and the TAK protocol version 1 protobuf
//! (`TakMessage { cotEvent }`, ATAK-CIV `commoncommo/core/impl/protobuf` `takmessage.proto`,
//! `cotevent.proto`, `detail.proto`, `contact.proto`, `track.proto`; the field numbers checked
//! against takproto 3.0.1's descriptors) in its two framings: mesh (UDP, `0xbf 0x01 0xbf` then
//! the message) and stream (TCP, `0xbf`, the message's length as a varint, the message).
//!
//! | CoT (XML / protobuf) | value |
//! |---|---|
//! | `uid` | `harrier.<uid_prefix>.track.<id>`: stable for the track's life, never reused |
//! | `type` | `cot.type` (default `a-u-G`, an unknown ground track) |
//! | `how` | `cot.how` (default `m-f`, machine-fused) |
//! | `time` / `sendTime` | the send time (`now_unix`) |
//! | `start` / `startTime` | the estimate's time (the track's last scan), at most the send time |
//! | `stale` / `staleTime` | the send time + `cot.stale_s` |
//! | `point lat lon` / `lat lon` | the estimate's position converted from the server's ENU frame (WGS-84 degrees) |
//! | `point hae` / `hae` | the height the frame gives (the frame's origin altitude + up), as is: the frame origin's `alt_m` is taken for an ellipsoid height |
//! | `point ce` / `ce` | 1σ horizontal error, m: √ of the larger eigenvalue of the horizontal 2×2 position covariance (the semi-major axis of the 1σ ellipse); `9999999` when the covariance lacks it |
//! | `point le` / `le` | 1σ vertical error, m: √var(z); `9999999` (CoT's "unknown") when z is not estimated (a planar track) |
//! | `detail/track course speed` / `detail.track` | course over ground (degrees from true north, [0, 360)) and ground speed (m/s) of the estimate |
//! | `detail/contact callsign` / `detail.contact.callsign` | `T` and the track id (`T12`), as the dashboard names it |
//! | `detail/remarks` / `detail.xmlDetail` | `harrier track <id>, <age> scans, last detection <s> s before` |
//!
//! With `cot.vehicles`, each vehicle is sent too ([`vehicle_event`]): `cot.vehicle_type`
//! (`a-f-A`, friendly air), uid `harrier.<uid_prefix>.uav.<label>`, callsign `UAV <label>`, at
//! its platform's position of its last scan.
//!
//! The estimate is the track's at its last scan (the tracker's time line), not predicted on.
//! Times are ISO-8601 UTC with milliseconds in XML and milliseconds since the UNIX epoch in
//! protobuf.

use std::fmt::Write as _;
use std::time::{Duration, SystemTime};

use harrier_core::linalg::ellipse_axes;
use harrier_engine::{TrackStatus, TrackView};
use harrier_link::geo::LocalFrame;
use nalgebra::{Matrix2, Vector3};
use prost::Message as _;

use crate::tracker::VehicleView;

/// CoT's value of an unknown `ce` / `le`.
pub const UNKNOWN_ERROR: f64 = 9_999_999.0;

/// What the configuration sets of every event.
#[derive(Debug, Clone, PartialEq)]
pub struct CotSettings {
    /// The CoT type of a track (`a-u-G`).
    pub cot_type: String,
    /// The CoT type of a vehicle (`a-f-A`).
    pub vehicle_type: String,
    /// The CoT `how` (`m-f`).
    pub how: String,
    /// The middle part of the uid (`harrier.<uid_prefix>.track.<id>`).
    pub uid_prefix: String,
    /// How long an event stays valid after it is sent, s.
    pub stale_s: f64,
}

/// One CoT event, encoding-neutral.
#[derive(Debug, Clone, PartialEq)]
pub struct CotEvent {
    /// Stable per track.
    pub uid: String,
    /// The CoT type.
    pub cot_type: String,
    /// The CoT `how`.
    pub how: String,
    /// Send time, UNIX ms.
    pub time_ms: u64,
    /// Time of the estimate, UNIX ms.
    pub start_ms: u64,
    /// End of validity, UNIX ms.
    pub stale_ms: u64,
    /// Latitude, degrees.
    pub lat: f64,
    /// Longitude, degrees.
    pub lon: f64,
    /// Height, m (see the module's table).
    pub hae: f64,
    /// 1σ horizontal error, m.
    pub ce: f64,
    /// 1σ vertical error, m.
    pub le: f64,
    /// Course and speed (`None` for a vehicle: not known from its scans).
    pub track: Option<CotTrack>,
    /// The contact's callsign.
    pub callsign: String,
    /// Free text.
    pub remarks: String,
}

/// The `<track>` detail.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CotTrack {
    /// Course over ground, degrees from true north, [0, 360).
    pub course: f64,
    /// Ground speed, m/s.
    pub speed: f64,
}

/// UNIX seconds to UNIX milliseconds; `None` unless finite and not before the epoch.
fn millis(unix_s: f64) -> Option<u64> {
    let ms = (unix_s * 1e3).round();
    // `as` saturates; a time past u64 ms is refused by the finiteness of the others anyway.
    (ms.is_finite() && ms >= 0.0).then_some(ms as u64)
}

/// √ of the larger eigenvalue of the horizontal 2×2 position covariance.
fn horizontal_sigma(track: &TrackView) -> Option<f64> {
    let (xx, yy, xy) = (
        track.cov_at(0, 0)?,
        track.cov_at(1, 1)?,
        track.cov_at(0, 1)?,
    );
    let ([s, _], _) = ellipse_axes(&Matrix2::new(xx, xy, xy, yy));
    s.is_finite().then_some(s)
}

/// The CoT event of a confirmed track sent at `now_unix`, `None` for a tentative track or an
/// estimate (or time) that is not finite.
pub fn track_event(
    track: &TrackView,
    frame: &LocalFrame,
    settings: &CotSettings,
    now_unix: f64,
) -> Option<CotEvent> {
    if track.status != TrackStatus::Confirmed || !track.state.iter().all(|v| v.is_finite()) {
        return None;
    }
    let [x, y, z, vx, vy, _] = track.state;
    let geo = frame.from_enu(&Vector3::new(x, y, z));
    if !(geo.lat_deg.is_finite() && geo.lon_deg.is_finite() && geo.alt_m.is_finite()) {
        return None;
    }
    let time_ms = millis(now_unix)?;
    let start_ms = millis(track.t)?.min(time_ms);
    let stale_ms = millis(now_unix + settings.stale_s)?;
    let ce = horizontal_sigma(track).unwrap_or(UNKNOWN_ERROR);
    let le = track
        .cov_at(2, 2)
        .map(f64::sqrt)
        .filter(|s| s.is_finite())
        .unwrap_or(UNKNOWN_ERROR);
    let since = (track.t - track.last_update).max(0.0);
    Some(CotEvent {
        uid: format!("harrier.{}.track.{}", settings.uid_prefix, track.id),
        cot_type: settings.cot_type.clone(),
        how: settings.how.clone(),
        time_ms,
        start_ms,
        stale_ms,
        lat: geo.lat_deg,
        lon: geo.lon_deg,
        hae: geo.alt_m,
        ce,
        le,
        track: Some(CotTrack {
            course: vx.atan2(vy).to_degrees().rem_euclid(360.0),
            speed: vx.hypot(vy),
        }),
        callsign: format!("T{}", track.id),
        remarks: format!(
            "harrier track {}, {} scans, last detection {since:.1} s before",
            track.id, track.age
        ),
    })
}

/// The CoT event of a vehicle (where the platform was at its last scan) sent at `now_unix`,
/// `None` when its position or time is not finite. Its uid is `harrier.<uid_prefix>.uav.<label>`,
/// its callsign `UAV <label>`, its `how` `m-g` (its own navigation); course, speed and the
/// errors are not known from its scans (no `<track>`, `ce`/`le` unknown).
pub fn vehicle_event(
    vehicle: &VehicleView,
    frame: &LocalFrame,
    settings: &CotSettings,
    now_unix: f64,
) -> Option<CotEvent> {
    if !vehicle.position.iter().all(|v| v.is_finite()) {
        return None;
    }
    let geo = frame.from_enu(&Vector3::from(vehicle.position));
    if !(geo.lat_deg.is_finite() && geo.lon_deg.is_finite() && geo.alt_m.is_finite()) {
        return None;
    }
    let time_ms = millis(now_unix)?;
    Some(CotEvent {
        uid: format!("harrier.{}.uav.{}", settings.uid_prefix, vehicle.vehicle),
        cot_type: settings.vehicle_type.clone(),
        how: "m-g".into(),
        time_ms,
        start_ms: millis(vehicle.last_t)?.min(time_ms),
        stale_ms: millis(now_unix + settings.stale_s)?,
        lat: geo.lat_deg,
        lon: geo.lon_deg,
        hae: geo.alt_m,
        ce: UNKNOWN_ERROR,
        le: UNKNOWN_ERROR,
        track: None,
        callsign: format!("UAV {}", vehicle.vehicle),
        remarks: format!(
            "harrier vehicle {}, {} scans",
            vehicle.vehicle, vehicle.scans
        ),
    })
}

/// UNIX ms as ISO-8601 UTC with milliseconds (`2026-11-26T19:15:00.123Z`).
fn iso(ms: u64) -> String {
    let t = SystemTime::UNIX_EPOCH + Duration::from_millis(ms);
    humantime::format_rfc3339_millis(t).to_string()
}

/// `text` escaped for an XML attribute value or element text.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// `TakMessage` (takmessage.proto); `takControl` (1) is not sent.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TakMessage {
    /// The event.
    #[prost(message, optional, tag = "2")]
    pub cot_event: Option<CotEventProto>,
}

/// `CotEvent` (cotevent.proto); `access`, `qos`, `opex` (2–4) are not sent.
#[derive(Clone, PartialEq, prost::Message)]
pub struct CotEventProto {
    /// `type`.
    #[prost(string, tag = "1")]
    pub r#type: String,
    /// `uid`.
    #[prost(string, tag = "5")]
    pub uid: String,
    /// `sendTime`, UNIX ms.
    #[prost(uint64, tag = "6")]
    pub send_time: u64,
    /// `startTime`, UNIX ms.
    #[prost(uint64, tag = "7")]
    pub start_time: u64,
    /// `staleTime`, UNIX ms.
    #[prost(uint64, tag = "8")]
    pub stale_time: u64,
    /// `how`.
    #[prost(string, tag = "9")]
    pub how: String,
    /// `lat`.
    #[prost(double, tag = "10")]
    pub lat: f64,
    /// `lon`.
    #[prost(double, tag = "11")]
    pub lon: f64,
    /// `hae`.
    #[prost(double, tag = "12")]
    pub hae: f64,
    /// `ce`.
    #[prost(double, tag = "13")]
    pub ce: f64,
    /// `le`.
    #[prost(double, tag = "14")]
    pub le: f64,
    /// `detail`.
    #[prost(message, optional, tag = "15")]
    pub detail: Option<DetailProto>,
}

/// `Detail` (detail.proto); `group`, `precisionLocation`, `status`, `takv` (3–6) are not sent.
#[derive(Clone, PartialEq, prost::Message)]
pub struct DetailProto {
    /// `xmlDetail`: the detail elements without a protobuf field of their own (`<remarks>`).
    #[prost(string, tag = "1")]
    pub xml_detail: String,
    /// `contact`.
    #[prost(message, optional, tag = "2")]
    pub contact: Option<ContactProto>,
    /// `track`.
    #[prost(message, optional, tag = "7")]
    pub track: Option<TrackProto>,
}

/// `Contact` (contact.proto).
#[derive(Clone, PartialEq, prost::Message)]
pub struct ContactProto {
    /// `endpoint` (empty: the tracks have none).
    #[prost(string, tag = "1")]
    pub endpoint: String,
    /// `callsign`.
    #[prost(string, tag = "2")]
    pub callsign: String,
}

/// `Track` (track.proto).
#[derive(Clone, PartialEq, prost::Message)]
pub struct TrackProto {
    /// `speed`, m/s.
    #[prost(double, tag = "1")]
    pub speed: f64,
    /// `course`, degrees from true north.
    #[prost(double, tag = "2")]
    pub course: f64,
}

/// The TAK protocol version 1 mesh header (UDP).
pub const MESH_HEADER: [u8; 3] = [0xbf, 0x01, 0xbf];
/// The TAK protocol version 1 stream magic byte (TCP).
pub const STREAM_MAGIC: u8 = 0xbf;

impl CotEvent {
    fn remarks_xml(&self) -> String {
        format!("<remarks>{}</remarks>", escape(&self.remarks))
    }

    /// The event as a CoT 2.0 XML document (with its XML declaration).
    pub fn to_xml(&self) -> String {
        let mut s = String::with_capacity(640);
        s.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>");
        // Writing to a String cannot fail.
        let _ = write!(
            s,
            "<event version=\"2.0\" uid=\"{}\" type=\"{}\" how=\"{}\" time=\"{}\" start=\"{}\" \
             stale=\"{}\"><point lat=\"{:.9}\" lon=\"{:.9}\" hae=\"{:.3}\" ce=\"{:.2}\" \
             le=\"{:.2}\"/><detail>",
            escape(&self.uid),
            escape(&self.cot_type),
            escape(&self.how),
            iso(self.time_ms),
            iso(self.start_ms),
            iso(self.stale_ms),
            self.lat,
            self.lon,
            self.hae,
            self.ce,
            self.le,
        );
        if let Some(t) = self.track {
            let _ = write!(
                s,
                "<track course=\"{:.2}\" speed=\"{:.3}\"/>",
                t.course, t.speed
            );
        }
        let _ = write!(
            s,
            "<contact callsign=\"{}\"/>{}</detail></event>",
            escape(&self.callsign),
            self.remarks_xml(),
        );
        s
    }

    /// The event as a TAK protocol version 1 message.
    pub fn to_proto(&self) -> TakMessage {
        TakMessage {
            cot_event: Some(CotEventProto {
                r#type: self.cot_type.clone(),
                uid: self.uid.clone(),
                send_time: self.time_ms,
                start_time: self.start_ms,
                stale_time: self.stale_ms,
                how: self.how.clone(),
                lat: self.lat,
                lon: self.lon,
                hae: self.hae,
                ce: self.ce,
                le: self.le,
                detail: Some(DetailProto {
                    xml_detail: self.remarks_xml(),
                    contact: Some(ContactProto {
                        endpoint: String::new(),
                        callsign: self.callsign.clone(),
                    }),
                    track: self.track.map(|t| TrackProto {
                        speed: t.speed,
                        course: t.course,
                    }),
                }),
            }),
        }
    }

    /// The protobuf message with the mesh header (one UDP datagram).
    pub fn to_mesh(&self) -> Vec<u8> {
        let m = self.to_proto();
        let mut out = Vec::with_capacity(MESH_HEADER.len() + m.encoded_len());
        out.extend_from_slice(&MESH_HEADER);
        m.encode_raw(&mut out);
        out
    }

    /// The protobuf message with the stream header (on a TCP stream).
    pub fn to_stream(&self) -> Vec<u8> {
        let m = self.to_proto();
        let mut out = Vec::with_capacity(1 + 10 + m.encoded_len());
        out.push(STREAM_MAGIC);
        prost::encoding::encode_varint(m.encoded_len() as u64, &mut out);
        m.encode_raw(&mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;

    fn settings() -> CotSettings {
        CotSettings {
            cot_type: "a-u-G".into(),
            vehicle_type: "a-f-A".into(),
            how: "m-f".into(),
            uid_prefix: "gcs1".into(),
            stale_s: 10.0,
        }
    }

    fn track(status: TrackStatus, state: [f64; 6]) -> TrackView {
        TrackView {
            id: 12,
            status,
            t: 1_790_000_000.25,
            state,
            // x, y, vx, vy: σx² 9, σy² 4 (axes aligned: ce = 3).
            cov: vec![
                vec![9.0, 0.0, 0.0, 0.0],
                vec![0.0, 4.0, 0.0, 0.0],
                vec![0.0, 0.0, 1.0, 0.0],
                vec![0.0, 0.0, 0.0, 1.0],
            ],
            cov_dims: vec![0, 1, 3, 4],
            updated: true,
            age: 30,
            last_update: 1_790_000_000.0,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    fn event() -> CotEvent {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        // 300 m east, 400 m north, 20 m up; 3 m/s east, 4 m/s north (course 36.87°).
        let t = track(TrackStatus::Confirmed, [300.0, 400.0, 20.0, 3.0, 4.0, 0.0]);
        track_event(&t, &frame, &settings(), 1_790_000_000.5).expect("an event")
    }

    #[test]
    fn a_confirmed_track_becomes_an_event_where_it_is() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        let e = event();
        let back = frame.to_enu(&harrier_link::geo::Geodetic {
            lat_deg: e.lat,
            lon_deg: e.lon,
            alt_m: e.hae,
        });
        assert!(
            (back - Vector3::new(300.0, 400.0, 20.0)).norm() < 1e-6,
            "{back}"
        );
        assert_eq!(e.uid, "harrier.gcs1.track.12");
        assert_eq!(e.callsign, "T12");
        assert_eq!(e.time_ms, 1_790_000_000_500);
        assert_eq!(e.start_ms, 1_790_000_000_250);
        assert_eq!(e.stale_ms, 1_790_000_010_500);
        assert!((e.ce - 3.0).abs() < 1e-12);
        assert_eq!(e.le, UNKNOWN_ERROR);
        let m = e.track.expect("course and speed");
        assert!((m.course - 36.869_897_645).abs() < 1e-6);
        assert!((m.speed - 5.0).abs() < 1e-12);
        assert_eq!(
            e.remarks,
            "harrier track 12, 30 scans, last detection 0.2 s before"
        );
    }

    #[test]
    fn ce_is_the_larger_axis_of_a_tilted_ellipse_and_le_the_vertical_sigma() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        let mut t = track(TrackStatus::Confirmed, [0.0; 6]);
        // Eigenvalues 5 ± 4 → 9 and 1; var z 0.25.
        t.cov = vec![
            vec![5.0, 4.0, 0.0],
            vec![4.0, 5.0, 0.0],
            vec![0.0, 0.0, 0.25],
        ];
        t.cov_dims = vec![0, 1, 2];
        let e = track_event(&t, &frame, &settings(), 1_790_000_001.0).expect("an event");
        assert!((e.ce - 3.0).abs() < 1e-12);
        assert!((e.le - 0.5).abs() < 1e-12);
        // No covariance at all: unknown.
        t.cov.clear();
        let e = track_event(&t, &frame, &settings(), 1_790_000_001.0).expect("an event");
        assert_eq!((e.ce, e.le), (UNKNOWN_ERROR, UNKNOWN_ERROR));
    }

    #[test]
    fn tentative_or_non_finite_tracks_make_no_event() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        let s = settings();
        let now = 1_790_000_000.5;
        assert!(track_event(&track(TrackStatus::Tentative, [0.0; 6]), &frame, &s, now).is_none());
        for i in 0..6 {
            for bad in [f64::NAN, f64::INFINITY] {
                let mut state = [0.0; 6];
                state[i] = bad;
                let t = track(TrackStatus::Confirmed, state);
                assert!(track_event(&t, &frame, &s, now).is_none(), "{i} {bad}");
            }
        }
        let ok = track(TrackStatus::Confirmed, [0.0; 6]);
        assert!(track_event(&ok, &frame, &s, f64::NAN).is_none());
        assert!(track_event(&ok, &frame, &s, -1.0).is_none());
        let mut t = ok.clone();
        t.t = f64::INFINITY;
        assert!(track_event(&t, &frame, &s, now).is_none());
        // West and due south: courses 270° and 180°, within [0, 360).
        let west = track(TrackStatus::Confirmed, [0.0, 0.0, 0.0, -2.0, 0.0, 0.0]);
        let e = track_event(&west, &frame, &s, now).expect("an event");
        assert!((e.track.expect("track").course - 270.0).abs() < 1e-9);
        let south = track(TrackStatus::Confirmed, [0.0, 0.0, 0.0, 0.0, -2.0, 0.0]);
        let e = track_event(&south, &frame, &s, now).expect("an event");
        assert!((e.track.expect("track").course - 180.0).abs() < 1e-9);
    }

    #[test]
    fn a_vehicle_is_friendly_air_where_its_platform_was() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        let mut v = VehicleView {
            vehicle: "8".into(),
            last_t: 1_790_000_000.0,
            scans: 40,
            sensors: vec!["cam".into()],
            position: [10.0, -20.0, 50.0],
            geodetic: harrier_core::detection::GeoPoint {
                lat_deg: 0.0,
                lon_deg: 0.0,
                alt_m: 0.0,
            },
        };
        let e = vehicle_event(&v, &frame, &settings(), 1_790_000_000.5).expect("an event");
        assert_eq!(
            (e.uid.as_str(), e.cot_type.as_str(), e.callsign.as_str()),
            ("harrier.gcs1.uav.8", "a-f-A", "UAV 8")
        );
        let back = frame.to_enu(&harrier_link::geo::Geodetic {
            lat_deg: e.lat,
            lon_deg: e.lon,
            alt_m: e.hae,
        });
        assert!((back - Vector3::new(10.0, -20.0, 50.0)).norm() < 1e-6);
        assert!(e.track.is_none());
        assert!(!e.to_xml().contains("<track"));
        let m = e
            .to_proto()
            .cot_event
            .and_then(|c| c.detail)
            .expect("detail");
        assert!(m.track.is_none());
        v.position[1] = f64::NAN;
        assert!(vehicle_event(&v, &frame, &settings(), 1_790_000_000.5).is_none());
    }

    #[test]
    fn the_xml_is_byte_exact_and_escapes_attribute_text() {
        let mut e = event();
        e.lat = 47.5;
        e.lon = 8.25;
        e.hae = 508.0;
        e.cot_type = "a-u-G\"<&>'".into();
        let xml = e.to_xml();
        assert_eq!(
            xml,
            "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>\
             <event version=\"2.0\" uid=\"harrier.gcs1.track.12\" \
             type=\"a-u-G&quot;&lt;&amp;&gt;&apos;\" how=\"m-f\" \
             time=\"2026-09-21T14:13:20.500Z\" start=\"2026-09-21T14:13:20.250Z\" \
             stale=\"2026-09-21T14:13:30.500Z\"><point lat=\"47.500000000\" \
             lon=\"8.250000000\" hae=\"508.000\" ce=\"3.00\" le=\"9999999.00\"/><detail>\
             <track course=\"36.87\" speed=\"5.000\"/><contact callsign=\"T12\"/>\
             <remarks>harrier track 12, 30 scans, last detection 0.2 s before</remarks>\
             </detail></event>"
        );
    }

    #[test]
    fn the_protobuf_round_trips_in_both_framings() {
        let e = event();
        let mesh = e.to_mesh();
        assert_eq!(mesh[..3], MESH_HEADER);
        let m = TakMessage::decode(&mesh[3..]).expect("decodes");
        assert_eq!(m, e.to_proto());
        let c = m.cot_event.expect("cotEvent");
        assert_eq!(c.uid, "harrier.gcs1.track.12");
        assert_eq!(c.r#type, "a-u-G");
        assert_eq!(
            (c.send_time, c.start_time, c.stale_time),
            (e.time_ms, e.start_ms, e.stale_ms)
        );
        assert_eq!(
            (c.lat, c.lon, c.hae, c.ce, c.le),
            (e.lat, e.lon, e.hae, e.ce, e.le)
        );
        let d = c.detail.expect("detail");
        assert_eq!(d.contact.expect("contact").callsign, "T12");
        assert_eq!(d.track.expect("track").speed, 5.0);

        let stream = e.to_stream();
        assert_eq!(stream[0], STREAM_MAGIC);
        let mut rest = &stream[1..];
        let m = TakMessage::decode_length_delimited(&mut rest).expect("decodes");
        assert!(rest.is_empty());
        assert_eq!(m, e.to_proto());
        // The message is longer than 127 bytes: a two-byte varint length.
        let len = e.to_proto().encoded_len();
        assert!(len > 127);
        assert_eq!(stream[1..3], [(len & 0x7f) as u8 | 0x80, (len >> 7) as u8]);
        assert_eq!(stream.len(), 3 + len);
    }
}
