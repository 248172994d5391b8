//! The dashboard's geographic map: the tile sources of `[map]` ([`MapService::open`]: the
//! MBTiles file opened and checked once, at start) as the page learns them from
//! `GET /api/v1/map` ([`MapBody`]), the MBTiles file's tiles for `GET /tiles/{z}/{x}/{y}`
//! ([`MapService::tile`], off the async runtime), and their counters.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use harrier_tiles::{MbTiles, Tile, TileId};
use serde::Serialize;
use utoipa::ToSchema;

use crate::config::Config;
use crate::error::LiveError;
use crate::prom::Family;

/// Where the page fetches the MBTiles file's tiles.
pub const TILES_PATH: &str = "/tiles/{z}/{x}/{y}";

/// What kind of tile source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum TileSourceKind {
    /// `map.tile_url`: fetched by the browser from wherever the template points.
    Url,
    /// `map.mbtiles`: served by this service at `/tiles/{z}/{x}/{y}`.
    Mbtiles,
}

/// One tile source of the map.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct TileSource {
    /// A name for the operator's layer choice.
    pub name: String,
    /// Where it comes from.
    pub kind: TileSourceKind,
    /// The URL template (`{z}`, `{x}`, `{y}`; `{s}`, `{r}` as Leaflet reads them).
    pub url: String,
    /// `png`, `jpg`, `webp` or `pbf`; for a URL, its extension's (absent when it has none).
    pub format: Option<String>,
    /// Raster tiles a browser draws as images (false for vector tiles, which the page does not
    /// draw).
    pub raster: bool,
    /// What the page must credit (text).
    pub attribution: Option<String>,
    /// Lowest zoom level with tiles.
    pub min_zoom: u8,
    /// Highest zoom level with tiles (the page scales them beyond).
    pub max_zoom: u8,
    /// The area with tiles, `[west, south, east, north]` (°); absent: the whole world.
    pub bounds: Option<[f64; 4]>,
}

/// The frame's WGS-84 origin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
pub struct OriginView {
    /// Latitude (°).
    pub lat_deg: f64,
    /// Longitude (°).
    pub lon_deg: f64,
    /// Height above the WGS-84 ellipsoid (m).
    pub alt_m: f64,
}

/// What the page needs to draw the live picture over a map: the tile sources (the first is
/// shown by default) and the frame the tracks are in.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct MapBody {
    /// The tile sources: `map.tile_url`'s, then `map.mbtiles`'s; empty: none configured.
    pub sources: Vec<TileSource>,
    /// The WGS-84 origin of the ENU frame every position of the API is in (`[frame] origin`).
    pub origin: OriginView,
    /// Up coordinate (m) of the ground plane.
    pub plane_z: f64,
}

/// The map's part of the service.
#[derive(Debug)]
pub struct MapService {
    /// What `GET /api/v1/map` answers.
    pub body: MapBody,
    /// `map.mbtiles`, open.
    tiles: Option<Arc<MbTiles>>,
    served: AtomicU64,
    not_modified: AtomicU64,
}

impl MapService {
    /// The sources of `config`'s `[map]`; opens and checks the MBTiles file (a blocking
    /// task: it reads the file). A missing or bad file is an error naming it.
    pub async fn open(config: &Config) -> Result<Self, LiveError> {
        let tiles = match config.map.mbtiles.as_str() {
            "" => None,
            path => {
                let path = Path::new(path).to_owned();
                let opened = tokio::task::spawn_blocking(move || MbTiles::open(&path))
                    .await
                    .map_err(|e| LiveError::Map(format!("opening map.mbtiles: {e}")))?;
                Some(Arc::new(opened.map_err(|e| LiveError::Map(e.to_string()))?))
            }
        };
        Ok(Self::new(config, tiles))
    }

    /// The sources of `config`'s `[map]` with `tiles` as its MBTiles file.
    pub fn new(config: &Config, tiles: Option<Arc<MbTiles>>) -> Self {
        let m = &config.map;
        let mut sources = Vec::new();
        if !m.tile_url.is_empty() {
            let format = url_format(&m.tile_url);
            sources.push(TileSource {
                name: "online".into(),
                kind: TileSourceKind::Url,
                url: m.tile_url.clone(),
                raster: format.as_deref() != Some("pbf"),
                format,
                attribution: m.url_attribution(),
                min_zoom: m.min_zoom,
                max_zoom: m.max_zoom,
                bounds: None,
            });
        }
        if let Some(t) = &tiles {
            let meta = t.metadata();
            sources.push(TileSource {
                name: meta.name.clone().unwrap_or_else(|| "offline".into()),
                kind: TileSourceKind::Mbtiles,
                url: TILES_PATH.into(),
                format: Some(meta.format.name().into()),
                raster: meta.format.is_raster(),
                attribution: meta.attribution.clone(),
                min_zoom: meta.min_zoom,
                max_zoom: meta.max_zoom,
                bounds: meta.bounds.map(|b| [b.west, b.south, b.east, b.north]),
            });
        }
        let o = config.frame.origin;
        Self {
            body: MapBody {
                sources,
                origin: OriginView {
                    lat_deg: o.lat_deg,
                    lon_deg: o.lon_deg,
                    alt_m: o.alt_m,
                },
                plane_z: config.frame.plane_z,
            },
            tiles,
            served: AtomicU64::new(0),
            not_modified: AtomicU64::new(0),
        }
    }

    /// The MBTiles file's tile at `id` (`None`: the file has none there); `Err` when there is no
    /// file or it could not be read. Runs the query on a blocking task.
    pub async fn tile(&self, id: TileId) -> Result<Option<Tile>, TileError> {
        let tiles = self.tiles.clone().ok_or(TileError::NoFile)?;
        tokio::task::spawn_blocking(move || tiles.tile(id))
            .await
            .map_err(|e| TileError::Read(e.to_string()))?
            .map_err(|e| TileError::Read(e.to_string()))
    }

    /// Counts a tile sent whole, or answered `304 Not Modified`.
    pub fn count(&self, not_modified: bool) {
        let c = if not_modified {
            &self.not_modified
        } else {
            &self.served
        };
        c.fetch_add(1, Ordering::Relaxed);
    }

    /// `harrier_tiles_served_total` (only with an MBTiles file).
    pub fn render_metrics(&self, out: &mut String) {
        if self.tiles.is_none() {
            return;
        }
        Family::counter(
            out,
            "harrier_tiles_served_total",
            "Map tiles answered from map.mbtiles at /tiles/{z}/{x}/{y}: sent (ok) or 304 \
             (not_modified); missing tiles and bad paths are refusals \
             (harrier_http_refused_total).",
        )
        .sample(&[("result", &"ok")], self.served.load(Ordering::Relaxed))
        .sample(
            &[("result", &"not_modified")],
            self.not_modified.load(Ordering::Relaxed),
        );
    }
}

/// Why a tile could not be answered.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TileError {
    /// No `map.mbtiles`.
    #[error("this server has no map.mbtiles: no tiles here")]
    NoFile,
    /// The file could not be read.
    #[error("reading the tile: {0}")]
    Read(String),
}

/// The format a tile URL template's extension names (`….png`, `….pbf?key=…`).
fn url_format(url: &str) -> Option<String> {
    let path = url.split(['?', '#']).next().unwrap_or(url);
    let last = path.rsplit('/').next().unwrap_or(path);
    let ext = last.rsplit_once('.')?.1.to_ascii_lowercase();
    harrier_tiles::TileFormat::from_metadata(&ext).map(|f| f.name().to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tile_url_is_the_first_source_with_the_format_of_its_extension() {
        let mut config = Config::default();
        assert!(MapService::new(&config, None).body.sources.is_empty());
        config.map.tile_url = "https://tile.openstreetmap.org/{z}/{x}/{y}.png".into();
        let s = MapService::new(&config, None);
        let src = &s.body.sources[0];
        assert_eq!(src.kind, TileSourceKind::Url);
        assert_eq!(src.format.as_deref(), Some("png"));
        assert!(src.raster);
        assert_eq!(
            src.attribution.as_deref(),
            Some("© OpenStreetMap contributors")
        );
        assert_eq!((src.min_zoom, src.max_zoom), (0, 19));
        assert_eq!(s.body.origin.lat_deg, config.frame.origin.lat_deg);
        assert_eq!(
            url_format("http://h/{z}/{x}/{y}.pbf?key=1").as_deref(),
            Some("pbf")
        );
        assert_eq!(url_format("http://127.0.0.1:9000/{z}/{x}/{y}"), None);
    }
}
