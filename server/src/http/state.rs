//! What the handlers read: [`ApiState`], in five parts a handler can take alone
//! (`State<Tracking>`, …, through [`FromRef`]), and the access rule ([`Auth`]).

use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use axum::extract::{FromRef, Request};
use axum::http::header;
use tokio::sync::{broadcast, mpsc, watch};

use super::serve::ConnectionStats;
use crate::config::ApiConfig;
use crate::feeds::FeedCounters;
use crate::gcs::GcsLink;
use crate::guidance::Guidance;
use crate::map::MapService;
use crate::metrics::Metrics;
use crate::tracker::{Command, Recent, ScanEvents, Snapshot};
use crate::wire::aircraft::AircraftList;
use crate::world::{TruthBody, WorldBody};
use harrier_recording::writer::Recorder;

/// What the handlers read (cloned for each request: handles and channels only).
#[derive(Debug, Clone)]
pub struct ApiState {
    /// The tracker and what it knows of the world.
    pub tracking: Tracking,
    /// The MAVLink link and the guidance, when configured.
    pub control: Control,
    /// The session recording.
    pub recording: Recording,
    /// Counters, access rule, uptime, stop signal.
    pub service: Service,
    /// The map's tile sources and the MBTiles file.
    pub map: Arc<MapService>,
}

/// The tracker's side: its snapshot, its scans, its commands; the truth and the static world.
#[derive(Debug, Clone)]
pub struct Tracking {
    /// The tracker's latest snapshot.
    pub snapshot: watch::Receiver<Arc<Snapshot>>,
    /// Every processed scan (the WebSocket's source).
    pub events: broadcast::Sender<Arc<ScanEvents>>,
    /// Recent scans and track histories.
    pub recent: Arc<Recent>,
    /// Requests to the tracker.
    pub commands: mpsc::Sender<Command>,
    /// The latest simulation truth.
    pub truth: watch::Receiver<Arc<TruthBody>>,
    /// Roads and obstacles of the configuration.
    pub world: Arc<WorldBody>,
    /// The manned aircraft of the ADS-B feed.
    pub aircraft: watch::Receiver<Arc<AircraftList>>,
}

/// A message every client sends within a period, serialised by the first client that needs it
/// and shared by the others while it is younger than the age they accept: with a swarm (254
/// vehicles, ≈ 260 kB a `vehicles` message) serialising it once per client and tick grew with
/// vehicles × clients.
#[derive(Debug, Default)]
pub struct SharedMessage(std::sync::Mutex<Option<(Instant, Arc<str>)>>);

impl SharedMessage {
    /// The message built at most `max_age` ago, else `build()`'s (kept for the others).
    pub(super) fn get(&self, max_age: Duration, build: impl FnOnce() -> String) -> Arc<str> {
        let mut m = self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        match &*m {
            Some((at, text)) if at.elapsed() <= max_age => Arc::clone(text),
            _ => {
                let text: Arc<str> = build().into();
                *m = Some((Instant::now(), Arc::clone(&text)));
                text
            }
        }
    }
}

/// The vehicles' side.
#[derive(Debug, Clone, Default)]
pub struct Control {
    /// The MAVLink GCS link, when configured.
    pub link: Option<GcsLink>,
    /// The guidance loop, when the link runs.
    pub guidance: Option<Guidance>,
    /// The WebSocket `vehicles` message, built once for every client of a period.
    pub vehicles_message: Arc<SharedMessage>,
}

/// The session recording.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// The session recorder (records the API actions; its file serves `/sessions`).
    pub recorder: Option<Recorder>,
    /// Why there is no recorder although `recorder.path` is set.
    pub error: Option<Arc<str>>,
}

/// The service itself.
#[derive(Debug, Clone)]
pub struct Service {
    /// The counters.
    pub metrics: Arc<Metrics>,
    /// The bearer tokens and whether reads need one.
    pub auth: Arc<Auth>,
    /// When the service started.
    pub started: Instant,
    /// Becomes `true` when the service stops (ends the WebSocket streams).
    pub stop: watch::Receiver<bool>,
    /// The API's connections, as [`super::serve`] counts them.
    pub connections: Arc<ConnectionStats>,
    /// The field-format feeds' counters.
    pub feeds: Arc<FeedCounters>,
}

impl FromRef<ApiState> for Tracking {
    fn from_ref(s: &ApiState) -> Self {
        s.tracking.clone()
    }
}

impl FromRef<ApiState> for Control {
    fn from_ref(s: &ApiState) -> Self {
        s.control.clone()
    }
}

impl FromRef<ApiState> for Recording {
    fn from_ref(s: &ApiState) -> Self {
        s.recording.clone()
    }
}

impl FromRef<ApiState> for Service {
    fn from_ref(s: &ApiState) -> Self {
        s.service.clone()
    }
}

impl FromRef<ApiState> for Arc<MapService> {
    fn from_ref(s: &ApiState) -> Self {
        Arc::clone(&s.map)
    }
}

/// The API's access rule.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Auth {
    /// The tokens accepted: `api.token` (named `main`, no expiry) and `api.tokens`.
    pub tokens: Vec<ApiToken>,
    /// Reads need a token too.
    pub reads: bool,
}

/// One accepted bearer token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiToken {
    /// Who holds it.
    pub name: String,
    /// The secret.
    pub secret: String,
    /// When it stops being accepted.
    pub expires: Option<SystemTime>,
}

/// What [`Auth::check`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum Verdict {
    Accepted,
    /// No `Authorization: Bearer` header (or WebSocket `token=`).
    Missing,
    /// A token no entry has.
    Wrong,
    /// A known token past its expiry.
    Expired {
        name: String,
        at: SystemTime,
    },
}

impl Auth {
    /// The rule of `[api]`: `main` (the service's token, from `HARRIER_TOKEN`, `api.token` or
    /// generated; named `main`, no expiry), then every `[[api.tokens]]` entry.
    pub fn new(main: &str, api: &ApiConfig) -> Self {
        let named = api.tokens.iter().map(|t| ApiToken {
            name: t.name.clone(),
            secret: t.token.clone(),
            // `Config::check` refuses a bad expiry; were one to get here, the token is refused
            // rather than accepted forever.
            expires: t.expiry().unwrap_or(Some(SystemTime::UNIX_EPOCH)),
        });
        let main = ApiToken {
            name: "main".into(),
            secret: main.into(),
            expires: None,
        };
        Self {
            tokens: std::iter::once(main).chain(named).collect(),
            reads: api.auth_reads,
        }
    }

    /// What `req` carries (header, or `token=` in the query of a WebSocket upgrade), judged at
    /// `now`. Every token is compared, each in constant time.
    pub(super) fn check(&self, req: &Request, now: SystemTime) -> Verdict {
        let header = req
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.strip_prefix("Bearer "));
        let query = req.uri().query().and_then(|q| {
            q.split('&')
                .find_map(|kv| kv.strip_prefix("token="))
                .filter(|_| req.uri().path().ends_with("/ws"))
        });
        let Some(given) = header.or(query) else {
            return Verdict::Missing;
        };
        let found = self.tokens.iter().fold(None, |found, t| {
            if constant_time_eq(given.as_bytes(), t.secret.as_bytes()) {
                Some(t)
            } else {
                found
            }
        });
        match found {
            None => Verdict::Wrong,
            Some(t) => match t.expires {
                Some(at) if now >= at => Verdict::Expired {
                    name: t.name.clone(),
                    at,
                },
                _ => Verdict::Accepted,
            },
        }
    }
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use axum::body::Body;

    use super::*;

    /// Clients within the age share one build of the message; past it, the next builds anew.
    #[test]
    fn a_shared_message_is_built_once_per_age() {
        let m = SharedMessage::default();
        let mut builds = 0;
        let build = |n: &mut i32| {
            *n += 1;
            format!("v{n}")
        };
        let a = m.get(Duration::from_secs(60), || build(&mut builds));
        let b = m.get(Duration::from_secs(60), || build(&mut builds));
        assert_eq!((&*a, &*b, builds), ("v1", "v1", 1));
        let c = m.get(Duration::ZERO, || build(&mut builds));
        assert_eq!((&*c, builds), ("v2", 2));
    }

    fn auth() -> Auth {
        Auth {
            tokens: vec![
                ApiToken {
                    name: "main".into(),
                    secret: "main-secret-0123456789".into(),
                    expires: None,
                },
                ApiToken {
                    name: "ci".into(),
                    secret: "ci-secret-0123456789ab".into(),
                    expires: Some(SystemTime::UNIX_EPOCH + Duration::from_secs(1000)),
                },
            ],
            reads: false,
        }
    }

    fn request(uri: &str, bearer: Option<&str>) -> Request {
        let mut r = Request::builder().uri(uri);
        if let Some(t) = bearer {
            r = r.header(header::AUTHORIZATION, format!("Bearer {t}"));
        }
        r.body(Body::empty()).expect("a request")
    }

    #[test]
    fn a_token_is_judged_by_header_and_on_the_websocket_by_query() {
        let a = auth();
        let at = |s| SystemTime::UNIX_EPOCH + Duration::from_secs(s);
        let check = |uri: &str, bearer, now| a.check(&request(uri, bearer), at(now));
        assert_eq!(check("/api/v1/x", None, 0), Verdict::Missing);
        assert_eq!(
            check("/api/v1/x", Some("main-secret-0123456789"), 0),
            Verdict::Accepted
        );
        assert_eq!(
            check("/api/v1/x", Some("main-secret-012345678"), 0),
            Verdict::Wrong
        );
        assert_eq!(
            check("/api/v1/x", Some("ci-secret-0123456789ab"), 999),
            Verdict::Accepted
        );
        assert_eq!(
            check("/api/v1/x", Some("ci-secret-0123456789ab"), 1000),
            Verdict::Expired {
                name: "ci".into(),
                at: at(1000)
            }
        );
        let q = "token=main-secret-0123456789";
        assert_eq!(
            check(&format!("/api/v1/ws?{q}"), None, 0),
            Verdict::Accepted
        );
        assert_eq!(
            check(&format!("/api/v1/tracks?{q}"), None, 0),
            Verdict::Missing
        );
    }

    #[test]
    fn the_rule_of_the_configuration_has_the_main_token_first_then_the_named_ones() {
        let api: ApiConfig = toml::from_str(
            "auth_reads = true\n\
             [[tokens]]\nname = \"ci\"\ntoken = \"ci-secret-0123456789ab\"\n\
             expires = \"1970-01-01T00:16:40Z\"\n\
             [[tokens]]\nname = \"ops\"\ntoken = \"ops-secret-0123456789\"\n",
        )
        .expect("an [api] table");
        let got = Auth::new("main-secret-0123456789", &api);
        let mut want = auth();
        want.tokens.push(ApiToken {
            name: "ops".into(),
            secret: "ops-secret-0123456789".into(),
            expires: None,
        });
        want.reads = true;
        assert_eq!(got, want);
    }

    #[test]
    fn constant_time_eq_compares_whole_slices() {
        assert!(constant_time_eq(b"abc", b"abc"));
        assert!(!constant_time_eq(b"abc", b"abd"));
        assert!(!constant_time_eq(b"abc", b"abcd"));
        assert!(constant_time_eq(b"", b""));
    }
}
