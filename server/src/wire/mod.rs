//! What leaves the server on a stream, as types: the WebSocket messages ([`WsMessage`], one per
//! `type`), the Zenoh `harrier-tracks/1` message ([`TracksMessage`]) and what they carry — a
//! track as the API sends it ([`TrackDto`], with its 95 % ellipse and ellipsoid, harrier-engine's),
//! a track event ([`TrackEventDto`]), a vehicle ([`VehicleEntry`]). The REST track routes send
//! the same [`TrackDto`]. Every type is in the OpenAPI components (`/api/openapi.json`), so a
//! client can generate its types from them.
//!
//! The transports (`http::ws`, `publish`) only serialise these; the domain types they are made
//! of ([`TrackView`](harrier_engine::TrackView), [`TrackEvent`](harrier_core::tracker::TrackEvent),
//! [`Snapshot`](crate::tracker::Snapshot), [`ScanEvents`](crate::tracker::ScanEvents)) stay off the
//! wire.
//!
//! Split by audience: `api` holds the service's own messages above. The encodings of the formats
//! other tools speak sit beside it, one pure file each (a track and the frame in, bytes out) —
//! but Foxglove's, which `harrier sessions export` also writes: harrier-recording's `foxglove`.

pub mod aircraft;
mod api;
pub mod asterix;
pub mod beast;
pub mod cot;
pub mod mode_s;
pub mod sbs;

pub use api::*;
