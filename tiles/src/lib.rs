//! # harrier-tiles
//!
//! Map tiles for the ground station's geographic map, with or without a network:
//!
//! - [`mbtiles`]: an MBTiles file (SQLite) opened read-only and checked once
//!   ([`MbTiles::open`]), tiles read by their XYZ address from a small pool of connections;
//!   [`writer`]: a new file written whole or not at all.
//! - [`mercator`]: Web Mercator tile arithmetic (XYZ, TMS rows, bounds).
//! - [`format`](mod@format): what a tile's bytes are and how they are served.
//! - `render` (feature `render`): the offline renderer, a deployment's roads and no-fly areas
//!   on a made-up ground, drawn with tiny-skia into PNG tiles over a zoom range and written as an
//!   MBTiles file (`harrier tiles render`, and `harrier demo`'s map on its first run).
//!
//! No async, no clock but the renderer's elapsed time; the live service calls the reader from
//! blocking tasks.

mod error;
pub mod format;
pub mod mbtiles;
pub mod mercator;
#[cfg(feature = "render")]
pub mod render;
pub mod writer;

pub use error::TilesError;
pub use format::TileFormat;
pub use mbtiles::{MbTiles, Metadata, Tile};
pub use mercator::{Bounds, TileId};
