//! What the in-process tests of the route files share: an [`ApiState`] over a real tracker
//! actor (real watch and broadcast channels, real counters), requests through [`super::app`]
//! with `oneshot`, and stand-ins for the MAVLink link and the guidance actors (their real
//! channel ends, with the test playing the actor).

use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use axum::body::Body;
use axum::http::{HeaderMap, Method, Request, StatusCode, header};
use harrier_core::detection::GeoPoint;
use harrier_core::measurement::MeasKind;
use harrier_core::measurement::{Geometry, SensorModel};
use serde_json::Value;
use tokio::sync::{broadcast, mpsc, watch};
use tower::ServiceExt as _;

use super::state::{ApiState, ApiToken, Auth, Control, Recording, Service, Tracking};
use crate::config::Config;
use crate::gcs::{self, GcsLink, LinkMetrics};
use crate::guidance::{Guidance, GuidanceMetrics, GuidanceRequest};
use crate::ingest::ReadyScan;
use crate::metrics::Metrics;
use crate::tracker::{Recent, Snapshot, TrackFilterState, TrackerActor};
use crate::world::{TruthBody, WorldBody};
use harrier_engine::SensorScan;
use harrier_recording::writer::{Recorder, SessionMeta};

/// The token the tests send.
pub(super) const TOKEN: &str = "test-token-0123456789abcdef";

/// Longest wait for anything in these tests.
pub(super) const WAIT: Duration = Duration::from_secs(5);

/// A service to ask: its state, the tracker's input and the ends the tests hold.
#[derive(Debug)]
pub(super) struct TestApp {
    /// What the router serves.
    pub(super) state: ApiState,
    scans: mpsc::Sender<ReadyScan>,
    /// The stop signal of the service (kept so that the WebSocket streams run).
    pub(super) stop: watch::Sender<bool>,
    /// The simulator's truth.
    pub(super) truth: watch::Sender<Arc<TruthBody>>,
}

/// A sensor of [`TestApp::scan_of`].
#[derive(Debug)]
pub(super) struct Sensor<'a> {
    /// Sensor id on the vehicle.
    pub(super) id: &'a str,
    /// Measurement kind.
    pub(super) kind: MeasKind,
    /// Platform position (ENU, m).
    pub(super) platform: [f64; 3],
    /// Noise standard deviation per component.
    pub(super) noise_std: &'a [f64],
}

/// A response, read whole.
#[derive(Debug)]
pub(super) struct Reply {
    pub(super) status: StatusCode,
    pub(super) headers: HeaderMap,
    pub(super) body: Vec<u8>,
}

impl Reply {
    /// The body as JSON.
    pub(super) fn json(&self) -> Value {
        serde_json::from_slice(&self.body).expect("a JSON body")
    }

    /// The `error` of a JSON error body (and the body has nothing else).
    pub(super) fn error(&self) -> String {
        let v = self.json();
        assert_eq!(v.as_object().map(|o| o.len()), Some(1), "{v}");
        v["error"].as_str().expect("an error message").to_owned()
    }
}

impl TestApp {
    /// A service without link, guidance or recording, whose WebSocket queue holds 256 scans.
    pub(super) fn new() -> Self {
        Self::with_queue(256)
    }

    /// The same with a WebSocket queue of `ws_queue` scans. The tracker runs on the test's
    /// runtime.
    pub(super) fn with_queue(ws_queue: usize) -> Self {
        Self::with_config(&Config::default(), ws_queue)
    }

    /// A service of `config`'s tracker and registration, whose WebSocket queue holds
    /// `ws_queue` scans.
    pub(super) fn with_config(config: &Config, ws_queue: usize) -> Self {
        let deployment = config.deployment();
        let estimator = TrackFilterState::of(&config.tracker);
        let engine = estimator
            .build(&deployment)
            .expect("the default track engine");
        let metrics = Arc::new(Metrics::default());
        let recent = Arc::new(Recent::default());
        let (snapshot_tx, snapshot) = watch::channel(Arc::new(Snapshot::default()));
        let (events, _) = broadcast::channel(ws_queue);
        let actor = TrackerActor::new(
            engine,
            deployment,
            estimator,
            config.tracker.reorder_window_s,
            Arc::clone(&metrics),
            Arc::clone(&recent),
            snapshot_tx,
            events.clone(),
        );
        let (scans, scan_rx) = mpsc::channel(64);
        let (commands, command_rx) = mpsc::channel(16);
        tokio::spawn(actor.run(scan_rx, command_rx));
        let (truth, truth_rx) = watch::channel(Arc::new(TruthBody::default()));
        let (stop, stop_rx) = watch::channel(false);
        let state = ApiState {
            tracking: Tracking {
                snapshot,
                events,
                recent,
                commands,
                truth: truth_rx,
                world: Arc::new(WorldBody::default()),
                aircraft: watch::channel(Arc::default()).1,
            },
            control: Control::default(),
            recording: Recording::default(),
            map: Arc::new(crate::map::MapService::new(config, None)),
            service: Service {
                metrics,
                auth: Arc::new(Auth {
                    tokens: vec![ApiToken {
                        name: "main".into(),
                        secret: TOKEN.into(),
                        expires: None,
                    }],
                    reads: false,
                }),
                started: Instant::now(),
                stop: stop_rx,
                connections: Arc::default(),
                feeds: Arc::default(),
            },
        };
        Self {
            state,
            scans,
            stop,
            truth,
        }
    }

    /// Reads need the token too (`api.auth_reads`).
    pub(super) fn reads_need_token(mut self) -> Self {
        let mut auth = (*self.state.service.auth).clone();
        auth.reads = true;
        self.state.service.auth = Arc::new(auth);
        self
    }

    /// Accepts one more token, `name`, that expired at `at`.
    pub(super) fn with_expired_token(mut self, name: &str, secret: &str, at: SystemTime) -> Self {
        let mut auth = (*self.state.service.auth).clone();
        auth.tokens.push(ApiToken {
            name: name.into(),
            secret: secret.into(),
            expires: Some(at),
        });
        self.state.service.auth = Arc::new(auth);
        self
    }

    /// A MAVLink link with no vehicle; the test plays its actor on the returned requests.
    pub(super) fn with_link(mut self) -> (Self, mpsc::Receiver<gcs::Request>) {
        let (requests, rx) = mpsc::channel(16);
        let (_, vehicles) = watch::channel(Arc::new(Vec::new()));
        self.state.control.link = Some(GcsLink {
            requests,
            vehicles,
            events: broadcast::channel(16).0,
            acks: broadcast::channel(16).0,
            endpoints: Vec::new(),
            gcs_endpoints: 0,
            metrics: Arc::new(LinkMetrics::default()),
            epoch: Instant::now(),
        });
        (self, rx)
    }

    /// A guidance with no assignment; the test plays its actor on the returned requests.
    pub(super) fn with_guidance(mut self) -> (Self, mpsc::Receiver<GuidanceRequest>) {
        let (requests, rx) = mpsc::channel(16);
        let (_, assignments) = watch::channel(Arc::new(Vec::new()));
        self.state.control.guidance = Some(Guidance {
            requests,
            assignments,
            events: broadcast::channel(16).0,
            metrics: Arc::new(GuidanceMetrics::default()),
        });
        (self, rx)
    }

    /// Records into a new session file in `dir`.
    pub(super) fn with_recording(mut self, dir: &std::path::Path) -> Self {
        let meta = SessionMeta {
            started_unix: 1.0e9,
            origin: Config::default().frame.origin,
            plane_z: 0.0,
            estimator: "ekf".into(),
            config_json: "{}".into(),
        };
        let path = dir.join("session.sqlite");
        let recorder =
            Recorder::open(&path, &meta, Duration::from_millis(10), 64).expect("a session file");
        self.state.recording.recorder = Some(recorder);
        self
    }

    /// One position scan of `vehicle` at `t` with `detections` (`[x, y]`, m); returns once the
    /// tracker has processed it.
    pub(super) async fn scan(&self, vehicle: u8, t: f64, detections: &[[f64; 2]]) {
        let detections: Vec<Vec<f64>> = detections.iter().map(|d| d.to_vec()).collect();
        let sensor = Sensor {
            id: "cam",
            kind: MeasKind::Position,
            platform: [0.0, 0.0, 50.0],
            noise_std: &[2.0, 2.0],
        };
        self.scan_of(vehicle, &sensor, t, detections).await;
    }

    /// One scan of `sensor` on `vehicle` at `t` with `detections` (FORMAT.md §3 layout of its
    /// kind); returns once the tracker has processed it.
    pub(super) async fn scan_of(
        &self,
        vehicle: u8,
        sensor: &Sensor<'_>,
        t: f64,
        detections: Vec<Vec<f64>>,
    ) {
        let mut snapshot = self.state.tracking.snapshot.clone();
        let before = snapshot.borrow().seq;
        let model = SensorModel::new(
            sensor.kind,
            Geometry::planar(0.0),
            nalgebra::Vector3::from(sensor.platform),
            sensor.noise_std,
            None,
        )
        .expect("a sensor model");
        let scan = ReadyScan {
            vehicle: vehicle.to_string(),
            sensor: sensor.id.into(),
            scan: SensorScan {
                t,
                sensor: model,
                detections,
            },
            platform: sensor.platform,
            platform_vel: [0.0; 3],
            geodetic: GeoPoint {
                lat_deg: 47.0,
                lon_deg: 8.0,
                alt_m: 540.0,
            },
            received: Instant::now(),
            noise_std: sensor.noise_std.to_vec(),
        };
        self.scans.send(scan).await.expect("the tracker runs");
        tokio::time::timeout(WAIT, snapshot.wait_for(|s| s.seq > before))
            .await
            .expect("the scan processed in time")
            .expect("the tracker runs");
    }

    /// Scans of one standing target at (100, 50) from vehicle 2 until it has a confirmed
    /// track; its id.
    pub(super) async fn confirmed_track(&self) -> u64 {
        for k in 0..20 {
            self.scan(2, f64::from(k), &[[100.0, 50.0]]).await;
            let snap = Arc::clone(&self.state.tracking.snapshot.borrow());
            if let Some(t) = snap
                .tracks
                .iter()
                .find(|t| t.status == harrier_engine::TrackStatus::Confirmed)
            {
                return t.id;
            }
        }
        panic!("no confirmed track after 20 scans");
    }

    /// Sends `req` through the whole router.
    pub(super) async fn call(&self, req: Request<Body>) -> Reply {
        let response = super::app(self.state.clone(), None, &[])
            .oneshot(req)
            .await
            .expect("the router never fails");
        let (parts, body) = response.into_parts();
        let body = axum::body::to_bytes(body, usize::MAX)
            .await
            .expect("a body");
        Reply {
            status: parts.status,
            headers: parts.headers,
            body: body.to_vec(),
        }
    }

    /// `GET uri`, without a token.
    pub(super) async fn get(&self, uri: &str) -> Reply {
        self.call(request(Method::GET, uri, None, None)).await
    }

    /// `GET uri` with the token.
    pub(super) async fn get_with_token(&self, uri: &str) -> Reply {
        self.call(request(Method::GET, uri, Some(TOKEN), None))
            .await
    }

    /// `method uri` with the token and a JSON body.
    pub(super) async fn send(&self, method: Method, uri: &str, json: &str) -> Reply {
        self.call(request(method, uri, Some(TOKEN), Some(json)))
            .await
    }

    /// `harrier_http_refused_total{reason, status}` as the service counts it.
    pub(super) fn refused(&self, reason: &str, status: u16) -> u64 {
        let text = self.state.service.metrics.render(0.0);
        let row = format!("harrier_http_refused_total{{reason=\"{reason}\",status=\"{status}\"}} ");
        text.lines()
            .find_map(|l| l.strip_prefix(&row))
            .map_or(0, |n| n.parse().expect("a count"))
    }

    /// Every refusal counted so far.
    pub(super) fn refused_total(&self) -> u64 {
        let text = self.state.service.metrics.render(0.0);
        text.lines()
            .filter(|l| l.starts_with("harrier_http_refused_total{"))
            .filter_map(|l| l.rsplit(' ').next()?.parse::<u64>().ok())
            .sum()
    }
}

/// A request: `token` as a bearer token, `json` as an `application/json` body.
pub(super) fn request(
    method: Method,
    uri: &str,
    token: Option<&str>,
    json: Option<&str>,
) -> Request<Body> {
    let mut r = Request::builder().method(method).uri(uri);
    if let Some(t) = token {
        r = r.header(header::AUTHORIZATION, format!("Bearer {t}"));
    }
    let body = match json {
        Some(j) => {
            r = r.header(header::CONTENT_TYPE, "application/json");
            Body::from(j.to_owned())
        }
        None => Body::empty(),
    };
    r.body(body).expect("a request")
}
