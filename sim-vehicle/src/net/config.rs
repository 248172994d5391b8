//! A vehicle's links as configured ([`LinkConfig`]) and why one could not be set up
//! ([`LinkError`]).

use harrier_link::frame::EndpointError;
use harrier_link::signing::Signing;

/// Errors from setting up links.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The connection string is not one of the supported forms.
    #[error(transparent)]
    BadAddress(#[from] EndpointError),
    /// A socket operation failed.
    #[error("{what} {address}: {source}")]
    Io {
        /// What was attempted.
        what: &'static str,
        /// The connection string.
        address: String,
        /// The error.
        source: std::io::Error,
    },
}

/// Links of one vehicle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkConfig {
    /// Connection strings, e.g. `udpout:127.0.0.1:14550` (GCS) and `udpin:0.0.0.0:14540` (API).
    pub endpoints: Vec<String>,
    /// MAVLink 2 signing on every link (`None`: off).
    pub signing: Option<Signing>,
}

impl LinkConfig {
    /// PX4 SITL-like defaults for vehicle `id`: GCS on `udpout:127.0.0.1:14550`, API on
    /// `udpin:0.0.0.0:{14540 + id - 1}`.
    pub fn px4_defaults(id: u8) -> Self {
        Self {
            endpoints: vec![
                "udpout:127.0.0.1:14550".to_owned(),
                format!("udpin:0.0.0.0:{}", 14540 + u16::from(id) - 1),
            ],
            signing: None,
        }
    }
}
