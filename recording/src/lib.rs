//! # harrier-recording
//!
//! The recording: a live session written into a SQLite file and read back offline
//! (RECORDING.md documents the file).
//!
//! - [`schema`]: the file's layout, its marks (application id, schema version) and
//!   `schema_problem`, which both sides use to recognise a session file;
//! - [`writer`]: the live recorder ([`writer::Recorder`]), one writer thread fed by `try_send`,
//!   and its counters ([`writer::RecorderStats`], also in Prometheus text);
//! - [`reader`]: sessions listed and summarised from a file opened read-only ([`reader::list`],
//!   [`reader::info`]);
//! - [`export`]: a session as a `gcs-scenario/1` directory ([`export::export`]), or as an MCAP
//!   file of Foxglove's schemas ([`export::mcap()`]);
//! - [`foxglove`]: the scene as Foxglove's schemas, which the live service's Foxglove feed also
//!   publishes.
//!
//! The live service (harrier-server) uses the writer, its `/sessions` routes the reader and the
//! export, and `harrier sessions` (harrier-tools) the reader and the export; nothing here
//! imports either.

pub mod export;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod foxglove;
pub mod reader;
pub mod schema;
pub mod writer;

#[cfg(test)]
mod tests;
