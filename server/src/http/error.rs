//! Every refusal of the API: one [`ApiError`], its status, its metric label and its JSON body
//! `{"error": "…"}`, and the mapping of the domain errors behind the routes onto it.
//!
//! A handler returns `Result<_, ApiError>` and never counts: [`ApiError::into_response`]
//! leaves the error in the response's extensions, and the middleware [`count_refusals`] counts
//! it once (`harrier_http_refused_total{reason, status}`) and logs the 5xx ones (axum's
//! error-handling example).

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::{JsonRejection, PathRejection, QueryRejection};
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::{Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use super::state::{Service, Verdict};
use crate::gcs::CommandError;
use crate::guidance::AssignError;
use crate::tracker::SetError;
use harrier_recording::reader::SessionError;

/// A refused request. `reason` is the label of `harrier_http_refused_total` where one status
/// has several causes.
#[derive(Debug, thiserror::Error)]
pub(super) enum ApiError {
    /// 400: a query (`query`), path (`path`), JSON body (`json`) or WebSocket upgrade
    /// (`websocket`) the route cannot read.
    #[error("{message}")]
    BadRequest {
        reason: &'static str,
        message: String,
    },
    /// 401 (`auth_missing`, `auth_wrong`, `auth_expired`), with `WWW-Authenticate: Bearer`.
    #[error("{}", unauthorized(.0).1)]
    Unauthorized(Verdict),
    /// 404 (`not_found`): no such route, track, vehicle, assignment or session.
    #[error("{0}")]
    NotFound(String),
    /// 409: the estimator cannot take the tracks over (`estimator`), the session cannot be
    /// exported (`export`), the vehicle is lost or busy, or already assigned (`conflict`).
    #[error("{message}")]
    Conflict {
        reason: &'static str,
        message: String,
    },
    /// 408 (`body_timeout`): a body that had not arrived by the body deadline of
    /// [`super::serve`].
    #[error("{0}")]
    RequestTimeout(String),
    /// 413: a body over the guard's limit (`too_large`) or axum's (`json`).
    #[error("{message}")]
    PayloadTooLarge {
        reason: &'static str,
        message: String,
    },
    /// 415 (`json`): a body without `Content-Type: application/json`.
    #[error("{0}")]
    UnsupportedMediaType(String),
    /// 422: JSON of the wrong shape (`json`), an unknown estimator or parameter (`estimator`),
    /// a command or assignment out of range (`invalid`).
    #[error("{message}")]
    Unprocessable {
        reason: &'static str,
        message: String,
    },
    /// 503: no MAVLink link or guidance, or it stopped (`no_link`); the tracker stopped
    /// (`stopped`); a command the link could not take (`command`).
    #[error("{message}")]
    Unavailable {
        reason: &'static str,
        message: String,
    },
    /// 500 (`internal`): the recording file could not be read.
    #[error("{0}")]
    Internal(String),
}

impl ApiError {
    /// 400 with its reason.
    pub(super) fn bad_request(reason: &'static str, message: impl Into<String>) -> Self {
        Self::BadRequest {
            reason,
            message: message.into(),
        }
    }

    /// 408, when `e` (a body that could not be read) is the body deadline passing.
    pub(super) fn body_timeout(e: &(dyn std::error::Error + 'static)) -> Option<Self> {
        let timed_out = std::iter::successors(Some(e), |e| e.source())
            .any(|e| e.is::<tower_http::timeout::TimeoutError>());
        timed_out.then(|| {
            Self::RequestTimeout(
                "the request body did not arrive in time (api.body_timeout_s)".into(),
            )
        })
    }

    /// 404.
    pub(super) fn not_found(message: impl Into<String>) -> Self {
        Self::NotFound(message.into())
    }

    /// 503 with its reason.
    pub(super) fn unavailable(reason: &'static str, message: impl Into<String>) -> Self {
        Self::Unavailable {
            reason,
            message: message.into(),
        }
    }

    /// The response status.
    pub(super) fn status_code(&self) -> StatusCode {
        match self {
            Self::BadRequest { .. } => StatusCode::BAD_REQUEST,
            Self::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            Self::NotFound(_) => StatusCode::NOT_FOUND,
            Self::Conflict { .. } => StatusCode::CONFLICT,
            Self::RequestTimeout(_) => StatusCode::REQUEST_TIMEOUT,
            Self::PayloadTooLarge { .. } => StatusCode::PAYLOAD_TOO_LARGE,
            Self::UnsupportedMediaType(_) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            Self::Unprocessable { .. } => StatusCode::UNPROCESSABLE_ENTITY,
            Self::Unavailable { .. } => StatusCode::SERVICE_UNAVAILABLE,
            Self::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The `reason` label of `harrier_http_refused_total`.
    pub(super) fn reason(&self) -> &'static str {
        match self {
            Self::BadRequest { reason, .. }
            | Self::Conflict { reason, .. }
            | Self::PayloadTooLarge { reason, .. }
            | Self::Unprocessable { reason, .. }
            | Self::Unavailable { reason, .. } => reason,
            Self::Unauthorized(v) => unauthorized(v).0,
            Self::NotFound(_) => "not_found",
            Self::RequestTimeout(_) => "body_timeout",
            Self::UnsupportedMediaType(_) => "json",
            Self::Internal(_) => "internal",
        }
    }
}

/// The reason, message and `WWW-Authenticate` challenge of a 401 (RFC 6750:
/// `error="invalid_token"` for a wrong or expired token).
fn unauthorized(v: &Verdict) -> (&'static str, String, &'static str) {
    match v {
        Verdict::Missing | Verdict::Accepted => (
            "auth_missing",
            "this request needs the API token: Authorization: Bearer <token>".to_owned(),
            "Bearer",
        ),
        Verdict::Wrong => (
            "auth_wrong",
            "the API token is not valid".to_owned(),
            "Bearer error=\"invalid_token\"",
        ),
        Verdict::Expired { name, at } => (
            "auth_expired",
            format!(
                "the API token {name:?} expired at {}",
                humantime::format_rfc3339_seconds(*at)
            ),
            "Bearer error=\"invalid_token\", error_description=\"expired\"",
        ),
    }
}

/// The body of every error response.
#[derive(Debug, Serialize, ToSchema)]
pub(super) struct ErrorBody {
    /// What went wrong.
    error: String,
}

impl IntoResponse for ApiError {
    /// `{"error": "…"}` with the status; the error itself goes into the response's extensions
    /// for [`count_refusals`].
    fn into_response(self) -> Response {
        let body = ErrorBody {
            error: self.to_string(),
        };
        let mut response = (self.status_code(), Json(body)).into_response();
        if let Self::Unauthorized(v) = &self {
            response.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static(unauthorized(v).2),
            );
        }
        response.extensions_mut().insert(Arc::new(self));
        response
    }
}

/// Middleware: counts each refusal once, by the [`ApiError`] its response carries, and logs the
/// server's own failures (5xx).
pub(super) async fn count_refusals(State(s): State<Service>, req: Request, next: Next) -> Response {
    let response = next.run(req).await;
    if let Some(e) = response.extensions().get::<Arc<ApiError>>() {
        let status = e.status_code();
        s.metrics.http_refused(e.reason(), status.as_u16());
        if status.is_server_error() {
            tracing::warn!(status = status.as_u16(), reason = e.reason(), "api: {e}");
        }
    }
    response
}

impl From<JsonRejection> for ApiError {
    /// A body axum's `Json` refused: 400 syntax, 415 content type, 422 data, 413 too large; all
    /// under `json`; 408 (`body_timeout`) when it did not arrive in time.
    fn from(e: JsonRejection) -> Self {
        if let Some(timeout) = Self::body_timeout(&e) {
            return timeout;
        }
        let message = e.body_text();
        let reason = "json";
        match e.status() {
            StatusCode::UNSUPPORTED_MEDIA_TYPE => Self::UnsupportedMediaType(message),
            StatusCode::UNPROCESSABLE_ENTITY => Self::Unprocessable { reason, message },
            StatusCode::PAYLOAD_TOO_LARGE => Self::PayloadTooLarge { reason, message },
            _ => Self::BadRequest { reason, message },
        }
    }
}

impl From<PathRejection> for ApiError {
    fn from(e: PathRejection) -> Self {
        Self::bad_request("path", e.body_text())
    }
}

impl From<QueryRejection> for ApiError {
    fn from(e: QueryRejection) -> Self {
        Self::bad_request("query", e.body_text())
    }
}

impl From<WebSocketUpgradeRejection> for ApiError {
    fn from(e: WebSocketUpgradeRejection) -> Self {
        Self::bad_request("websocket", e.body_text())
    }
}

impl From<SetError> for ApiError {
    fn from(e: SetError) -> Self {
        let reason = "estimator";
        match e {
            SetError::Invalid(message) => Self::Unprocessable { reason, message },
            SetError::Handover(message) => Self::Conflict { reason, message },
        }
    }
}

impl From<CommandError> for ApiError {
    fn from(e: CommandError) -> Self {
        let message = e.to_string();
        match e {
            CommandError::UnknownVehicle(_) => Self::NotFound(message),
            CommandError::Lost(..) | CommandError::Busy(..) => Self::Conflict {
                reason: "conflict",
                message,
            },
            CommandError::Stopped => Self::unavailable("no_link", message),
            CommandError::NotACommand => Self::unavailable("command", message),
        }
    }
}

impl From<AssignError> for ApiError {
    fn from(e: AssignError) -> Self {
        let message = e.to_string();
        match e {
            AssignError::Invalid(_) => Self::Unprocessable {
                reason: "invalid",
                message,
            },
            AssignError::NotFound(_) => Self::NotFound(message),
            AssignError::Conflict(_) => Self::Conflict {
                reason: "conflict",
                message,
            },
            AssignError::Stopped => Self::unavailable("no_link", message),
        }
    }
}

impl From<SessionError> for ApiError {
    fn from(e: SessionError) -> Self {
        match e {
            SessionError::NotFound { .. } => Self::NotFound(e.to_string()),
            SessionError::Export { .. } => Self::Conflict {
                reason: "export",
                message: e.to_string(),
            },
            e => Self::Internal(e.to_string()),
        }
    }
}
