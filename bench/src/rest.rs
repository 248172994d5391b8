//! HTTP/1 over real sockets (hyper's client connection): one-off requests for the server's
//! counters, and the REST load — concurrent keep-alive connections, each sending its next `GET`
//! as soon as the last response's body is read.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use http_body_util::{BodyExt as _, Empty, Full};
use hyper::body::Bytes;
use hyper::client::conn::http1::SendRequest;
use hyper_util::rt::TokioIo;
use serde::Serialize;

use super::stats::{Histogram, Percentiles};

/// Where the API is and how to ask it.
#[derive(Debug, Clone)]
pub(super) struct Api {
    /// Its address.
    pub addr: SocketAddr,
    /// The bearer token sent with every request (`None`: none).
    pub token: Option<String>,
}

/// Longest wait for one request of the tool's own (counters, the final state).
const REQUEST_TIMEOUT: Duration = Duration::from_secs(10);

impl Api {
    fn request(&self, path: &str) -> anyhow::Result<hyper::Request<Empty<Bytes>>> {
        let mut r = hyper::Request::get(path).header(hyper::header::HOST, self.addr.to_string());
        if let Some(t) = &self.token {
            r = r.header(hyper::header::AUTHORIZATION, format!("Bearer {t}"));
        }
        Ok(r.body(Empty::new())?)
    }

    /// A keep-alive connection.
    async fn connect<B>(&self) -> anyhow::Result<SendRequest<B>>
    where
        B: hyper::body::Body + Send + 'static,
        B::Data: Send,
        B::Error: Into<Box<dyn std::error::Error + Send + Sync>>,
    {
        let stream = tokio::net::TcpStream::connect(self.addr)
            .await
            .with_context(|| format!("cannot connect to the API at {}", self.addr))?;
        stream.set_nodelay(true)?;
        let (sender, conn) = hyper::client::conn::http1::handshake(TokioIo::new(stream)).await?;
        tokio::spawn(conn);
        Ok(sender)
    }

    /// `GET path` on a fresh connection: the body of a 200 answer, else an error.
    pub(super) async fn get(&self, path: &str) -> anyhow::Result<String> {
        let fetch = async {
            let mut sender = self.connect().await?;
            let res = sender.send_request(self.request(path)?).await?;
            let status = res.status();
            let body = res.into_body().collect().await?.to_bytes();
            let body = String::from_utf8_lossy(&body).into_owned();
            anyhow::ensure!(status.is_success(), "GET {path}: {status}: {body}");
            Ok(body)
        };
        tokio::time::timeout(REQUEST_TIMEOUT, fetch)
            .await
            .with_context(|| format!("GET {path}: no answer within {REQUEST_TIMEOUT:?}"))?
    }

    /// `POST path` with a JSON `body` on a fresh connection: the body of a 2xx answer, else an
    /// error.
    pub(super) async fn post(
        &self,
        path: &str,
        body: &serde_json::Value,
    ) -> anyhow::Result<String> {
        let fetch = async {
            let mut sender = self.connect().await?;
            let mut r = hyper::Request::post(path)
                .header(hyper::header::HOST, self.addr.to_string())
                .header(hyper::header::CONTENT_TYPE, "application/json");
            if let Some(t) = &self.token {
                r = r.header(hyper::header::AUTHORIZATION, format!("Bearer {t}"));
            }
            let request = r.body(Full::new(Bytes::from(body.to_string())))?;
            let res = sender.send_request(request).await?;
            let status = res.status();
            let text = res.into_body().collect().await?.to_bytes();
            let text = String::from_utf8_lossy(&text).into_owned();
            anyhow::ensure!(status.is_success(), "POST {path}: {status}: {text}");
            Ok(text)
        };
        tokio::time::timeout(REQUEST_TIMEOUT, fetch)
            .await
            .with_context(|| format!("POST {path}: no answer within {REQUEST_TIMEOUT:?}"))?
    }
}

/// What the REST load measured.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RestReport {
    /// Concurrent connections.
    pub connections: usize,
    /// Path requested.
    pub path: String,
    /// How long the load ran (s).
    pub duration_s: f64,
    /// Responses with status 200.
    pub ok: u64,
    /// Responses with another status.
    pub non_ok: u64,
    /// Failed requests and connections (each connection is re-opened after a failure).
    pub errors: u64,
    /// 200 responses per second.
    pub req_per_s: f64,
    /// Request → complete response body, over every response (ms).
    pub latency_ms: Percentiles,
}

/// The REST load while it runs.
#[derive(Debug, Default)]
pub(super) struct RestLoad {
    ok: AtomicU64,
    non_ok: AtomicU64,
    errors: AtomicU64,
    latency: Histogram,
}

impl RestLoad {
    /// 200 responses so far.
    pub(super) fn ok(&self) -> u64 {
        self.ok.load(Relaxed)
    }

    /// `connections` connections send `GET path` back to back for `duration`.
    pub(super) async fn run(
        self: Arc<Self>,
        api: Api,
        path: String,
        connections: usize,
        duration: Duration,
    ) -> RestReport {
        let start = Instant::now();
        let until = start + duration;
        let tasks: Vec<_> = (0..connections)
            .map(|_| tokio::spawn(Arc::clone(&self).connection(api.clone(), path.clone(), until)))
            .collect();
        for t in tasks {
            if t.await.is_err() {
                self.errors.fetch_add(1, Relaxed);
            }
        }
        let elapsed = start.elapsed().as_secs_f64();
        let ok = self.ok.load(Relaxed);
        RestReport {
            connections,
            path,
            duration_s: elapsed,
            ok,
            non_ok: self.non_ok.load(Relaxed),
            errors: self.errors.load(Relaxed),
            req_per_s: if elapsed > 0.0 {
                ok as f64 / elapsed
            } else {
                0.0
            },
            latency_ms: self.latency.percentiles(),
        }
    }

    /// One connection's loop, re-connecting after a failure (after 10 ms, so that a refusing
    /// server is not hammered).
    async fn connection(self: Arc<Self>, api: Api, path: String, until: Instant) {
        let mut sender = None;
        while Instant::now() < until {
            let s = match &mut sender {
                Some(s) => s,
                None => match api.connect().await {
                    Ok(s) => sender.insert(s),
                    Err(_) => {
                        self.errors.fetch_add(1, Relaxed);
                        tokio::time::sleep(Duration::from_millis(10)).await;
                        continue;
                    }
                },
            };
            let Ok(request) = api.request(&path) else {
                self.errors.fetch_add(1, Relaxed);
                return;
            };
            let t0 = Instant::now();
            let answer = async {
                s.ready().await?;
                let res = s.send_request(request).await?;
                let status = res.status();
                res.into_body().collect().await?;
                Ok::<_, hyper::Error>(status)
            };
            match tokio::time::timeout_at(until.into(), answer).await {
                Ok(Ok(status)) => {
                    self.latency.record_s(t0.elapsed().as_secs_f64());
                    if status == hyper::StatusCode::OK {
                        self.ok.fetch_add(1, Relaxed);
                    } else {
                        self.non_ok.fetch_add(1, Relaxed);
                    }
                }
                Ok(Err(_)) => {
                    self.errors.fetch_add(1, Relaxed);
                    sender = None;
                }
                // The load's end came during the request: not counted.
                Err(_) => return,
            }
        }
    }
}
