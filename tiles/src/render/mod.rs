//! The offline tile renderer: a [`TileWorld`] (roads, areas, a name, in longitude and
//! latitude) drawn into raster tiles over a zoom range around it and written as an MBTiles file
//! ([`render`]), so that a ground station shows a map of its area with no network. Pure but for
//! the file it writes; the tiles are rendered on every core (`RenderOptions::threads`) and
//! written in one transaction by the calling thread.

mod ground;
mod raster;
mod text;

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use crate::error::TilesError;
use crate::mercator::{Bounds, MAX_LAT_DEG, TileId};
use crate::writer::MbTilesWriter;

/// Changes whenever the renderer draws differently: part of [`TileWorld::fingerprint`], so that
/// cached files made by an older renderer are made again.
pub const RENDERER_VERSION: u32 = 1;

/// The attribution of generated tiles.
pub const ATTRIBUTION: &str =
    "Harrier offline map: the deployment's roads and no-fly areas on a made-up ground";

/// A longitude and latitude (°).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LonLat {
    /// Longitude (°).
    pub lon: f64,
    /// Latitude (°).
    pub lat: f64,
}

/// A road: its centre line and width.
#[derive(Debug, Clone, PartialEq)]
pub struct GeoRoad {
    /// Its name (drawn from zoom 15 on; empty: none).
    pub name: String,
    /// Width on the ground (m).
    pub width_m: f64,
    /// Centre line.
    pub points: Vec<LonLat>,
}

/// An area to keep out of: a disc.
#[derive(Debug, Clone, PartialEq)]
pub struct GeoArea {
    /// Its name (drawn from zoom 15 on; empty: none).
    pub name: String,
    /// Centre.
    pub center: LonLat,
    /// Radius (m).
    pub radius_m: f64,
}

/// What a generated map shows.
#[derive(Debug, Clone, PartialEq)]
pub struct TileWorld {
    /// The map's name: the file's `name` and a label at `center`.
    pub name: String,
    /// The middle of the map (the deployment's origin): where the name goes, and the latitude
    /// the ground is laid out at.
    pub center: LonLat,
    /// Roads.
    pub roads: Vec<GeoRoad>,
    /// Areas.
    pub areas: Vec<GeoArea>,
}

/// Metres per degree of latitude (mean; for margins only).
const M_PER_DEG: f64 = 111_320.0;

impl TileWorld {
    /// The rectangle holding everything, widened by `margin_m` on every side.
    pub fn bounds(&self, margin_m: f64) -> Bounds {
        let mut b = [
            self.center.lon,
            self.center.lat,
            self.center.lon,
            self.center.lat,
        ];
        let mut add = |p: LonLat, r_m: f64| {
            let dlat = r_m / M_PER_DEG;
            let dlon = r_m / (M_PER_DEG * p.lat.to_radians().cos().max(0.01));
            b = [
                b[0].min(p.lon - dlon),
                b[1].min(p.lat - dlat),
                b[2].max(p.lon + dlon),
                b[3].max(p.lat + dlat),
            ];
        };
        for r in &self.roads {
            for &p in &r.points {
                add(p, margin_m);
            }
        }
        for a in &self.areas {
            add(a.center, a.radius_m + margin_m);
        }
        add(self.center, margin_m);
        Bounds {
            west: b[0].max(-180.0),
            south: b[1].max(-MAX_LAT_DEG),
            east: b[2].min(180.0),
            north: b[3].min(MAX_LAT_DEG),
        }
    }

    /// A 64-bit fingerprint of this world as `options` would render it with this renderer
    /// (FNV-1a of its full description): a cached file made from a different world, range or
    /// renderer has a different one.
    pub fn fingerprint(&self, options: &RenderOptions) -> u64 {
        let text = format!(
            "{RENDERER_VERSION}|{self:?}|{}-{}|{}",
            options.min_zoom, options.max_zoom, options.margin_m
        );
        text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
        })
    }
}

/// What to render.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Lowest zoom level.
    pub min_zoom: u8,
    /// Highest zoom level (a map library scales its tiles beyond it).
    pub max_zoom: u8,
    /// Ground around the world's features (m).
    pub margin_m: f64,
    /// Rendering threads (at least 1).
    pub threads: usize,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            min_zoom: 12,
            max_zoom: 17,
            margin_m: 2_500.0,
            threads: std::thread::available_parallelism().map_or(1, usize::from),
        }
    }
}

impl RenderOptions {
    /// The checks: a zoom range within 0–22 (deeper would be millions of tiles of nothing), a
    /// finite margin of at most 50 km.
    pub fn check(&self) -> Result<(), String> {
        if self.min_zoom > self.max_zoom || self.max_zoom > 22 {
            return Err(format!(
                "zoom levels {}–{}: expected min ≤ max ≤ 22",
                self.min_zoom, self.max_zoom
            ));
        }
        if !(self.margin_m.is_finite() && (0.0..=50_000.0).contains(&self.margin_m)) {
            return Err(format!("margin {} m: expected 0–50 000 m", self.margin_m));
        }
        Ok(())
    }
}

/// Where a rendering is (for a progress line).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Tiles written.
    pub done: u64,
    /// Tiles in all.
    pub total: u64,
}

/// What a rendering made.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderStats {
    /// The rectangle covered.
    pub bounds: Bounds,
    /// Tiles written.
    pub tiles: u64,
    /// Bytes of PNG written.
    pub bytes: u64,
    /// Wall time.
    pub elapsed: Duration,
}

/// One tile of `world` as a PNG (every zoom level; tiles outside the world's bounds show the
/// ground alone).
pub fn tile(world: &TileWorld, id: TileId) -> Result<Vec<u8>, TilesError> {
    raster::Scene::new(world, id.z)
        .tile(id)
        .map_err(|e| TilesError::File {
            path: format!("tile {}/{}/{}", id.z, id.x, id.y),
            message: e,
        })
}

/// Most tiles a rendering may make (a typo in a margin or zoom level must not fill a disk).
pub const MAX_TILES: u64 = 200_000;

/// Renders `world` into the MBTiles file `out` (refused if it exists, unless `overwrite`),
/// calling `progress` now and then. The file appears whole at the end, or not at all.
pub fn render(
    world: &TileWorld,
    options: &RenderOptions,
    out: &Path,
    overwrite: bool,
    mut progress: impl FnMut(Progress),
) -> Result<RenderStats, TilesError> {
    let started = Instant::now();
    options.check().map_err(|e| TilesError::file(out, e))?;
    // As the file will say it (7 decimals): a reader asks for exactly the tiles these touch.
    let bounds = world.bounds(options.margin_m);
    let bounds = Bounds::parse(&bounds.to_metadata()).unwrap_or(bounds);
    let ranges: Vec<_> = (options.min_zoom..=options.max_zoom)
        .map(|z| bounds.tile_range(z))
        .collect();
    let total: u64 = ranges.iter().map(|r| r.len()).sum();
    if total > MAX_TILES {
        return Err(TilesError::file(
            out,
            format!(
                "{total} tiles is more than {MAX_TILES}: lower the highest zoom level or the margin"
            ),
        ));
    }
    let mut writer = MbTilesWriter::create(out, overwrite)?;
    let center_zoom = options.max_zoom.min(options.min_zoom.max(15));
    for (k, v) in [
        ("name", world.name.clone()),
        ("format", "png".into()),
        ("type", "baselayer".into()),
        ("version", RENDERER_VERSION.to_string()),
        (
            "description",
            format!("{} (generated by harrier tiles)", world.name),
        ),
        ("attribution", ATTRIBUTION.into()),
        ("bounds", bounds.to_metadata()),
        (
            "center",
            format!(
                "{:.7},{:.7},{center_zoom}",
                world.center.lon, world.center.lat
            ),
        ),
        ("minzoom", options.min_zoom.to_string()),
        ("maxzoom", options.max_zoom.to_string()),
        (
            "harrier_world",
            format!("{:016x}", world.fingerprint(options)),
        ),
    ] {
        writer.set_metadata(k, &v)?;
    }
    let scenes: Vec<raster::Scene> = (options.min_zoom..=options.max_zoom)
        .map(|z| raster::Scene::new(world, z))
        .collect();
    let tiles: Vec<TileId> = ranges
        .iter()
        .flat_map(|r| r.iter().collect::<Vec<_>>())
        .collect();
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let (tx, rx) = std::sync::mpsc::sync_channel::<(TileId, Result<Vec<u8>, String>)>(256);
    let mut bytes = 0u64;
    let mut done = 0u64;
    let written = std::thread::scope(|s| -> Result<(), TilesError> {
        for _ in 0..options.threads.max(1) {
            let tx = tx.clone();
            let (next, stop, tiles, scenes) = (&next, &stop, &tiles, &scenes);
            s.spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    let Some(&id) = tiles.get(next.fetch_add(1, Ordering::Relaxed)) else {
                        break;
                    };
                    let scene = &scenes[usize::from(id.z - options.min_zoom)];
                    if tx.send((id, scene.tile(id))).is_err() {
                        break;
                    }
                }
            });
        }
        drop(tx);
        let step = (total / 100).max(1);
        let result = rx.iter().try_for_each(|(id, png)| {
            let png = png.map_err(|e| {
                TilesError::file(out, format!("tile {}/{}/{}: {e}", id.z, id.x, id.y))
            })?;
            writer.insert(id, &png)?;
            bytes += png.len() as u64;
            done += 1;
            if done % step == 0 || done == total {
                progress(Progress { done, total });
            }
            Ok(())
        });
        // On an error the renderers stop at their next tile.
        stop.store(true, Ordering::Relaxed);
        drop(rx);
        result
    });
    written?;
    writer.finish()?;
    Ok(RenderStats {
        bounds,
        tiles: done,
        bytes,
        elapsed: started.elapsed(),
    })
}

#[cfg(test)]
mod tests;
