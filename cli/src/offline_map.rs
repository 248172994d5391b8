//! The offline map of a deployment: its world (roads and no-fly areas, as `GET /api/v1/world`
//! serves them) in WGS-84 for the tile renderer ([`tile_world`]), and the demo's MBTiles file,
//! rendered once and cached ([`offline_tiles`]). `harrier tiles render` and `harrier demo` both
//! use it.

use std::path::PathBuf;

use harrier_link::geo::LocalFrame;
use harrier_server::config::Config;
use harrier_server::world::WorldBody;
use harrier_tiles::MbTiles;
use harrier_tiles::render::{self, GeoArea, GeoRoad, LonLat, RenderOptions, TileWorld};

/// The name the demo's map carries.
pub const DEMO_NAME: &str = "HARRIER DEMO";

/// The world of `config` as the tile renderer takes it: the roads (their centre lines as
/// `GET /api/v1/world` serves them, 6 m wide when the configuration gives no width) and the
/// obstacles, from the frame's ENU on the ground plane to WGS-84.
pub fn tile_world(config: &Config, name: &str) -> TileWorld {
    let frame = LocalFrame::new(config.frame.origin);
    let z = config.frame.plane_z;
    let geo = |x: f64, y: f64| {
        let g = frame.from_enu(&nalgebra::Vector3::new(x, y, z));
        LonLat {
            lon: g.lon_deg,
            lat: g.lat_deg,
        }
    };
    let world = WorldBody::of(config);
    TileWorld {
        name: name.to_owned(),
        center: geo(0.0, 0.0),
        roads: world
            .roads
            .iter()
            .map(|r| GeoRoad {
                name: r.id.clone(),
                width_m: r.width_m.unwrap_or(6.0),
                points: r.points.iter().map(|p| geo(p[0], p[1])).collect(),
            })
            .collect(),
        areas: world
            .obstacles
            .iter()
            .map(|o| GeoArea {
                name: "NO-FLY".into(),
                center: geo(o.x_m, o.y_m),
                radius_m: o.radius_m,
            })
            .collect(),
    }
}

/// Where cached files go: `$XDG_CACHE_HOME/harrier`, else `~/.cache/harrier`, else the
/// system's temporary directory.
fn cache_dir() -> PathBuf {
    std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .map_or_else(
            || std::env::temp_dir().join("harrier-cache"),
            |d| d.join("harrier"),
        )
}

/// The demo's offline map: the MBTiles file of `config`'s world in the cache
/// (`…/harrier/tiles/demo-FINGERPRINT.mbtiles`: another world, zoom range or renderer has
/// another name), rendered on the first run (a few seconds, logged) and opened as it is after;
/// the error says what failed.
pub async fn offline_tiles(config: &Config) -> Result<PathBuf, String> {
    let world = tile_world(config, DEMO_NAME);
    let options = RenderOptions::default();
    let mut dir = cache_dir().join("tiles");
    if std::fs::create_dir_all(&dir).is_err() {
        dir = std::env::temp_dir().join("harrier-tiles");
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let path = dir.join(format!("demo-{:016x}.mbtiles", world.fingerprint(&options)));
    if MbTiles::open(&path).is_ok() {
        tracing::info!(path = %path.display(), "offline map: cached tiles");
        return Ok(path);
    }
    tracing::info!(path = %path.display(), "offline map: rendering the demo's world (once)");
    let out = path.clone();
    let stats = tokio::task::spawn_blocking(move || {
        let mut quarter = 0;
        // Several demos may render the same file at once: each writes its own partial file and
        // renames it into place, so the last one wins with the same tiles.
        render::render(&world, &options, &out, true, |p| {
            let q = 4 * p.done / p.total.max(1);
            if q > quarter {
                quarter = q;
                tracing::info!("offline map: {}/{} tiles", p.done, p.total);
            }
        })
    })
    .await
    .map_err(|e| e.to_string())?
    .map_err(|e| e.to_string())?;
    tracing::info!(
        tiles = stats.tiles,
        mb = stats.bytes as f64 / 1e6,
        seconds = stats.elapsed.as_secs_f64(),
        "offline map rendered"
    );
    Ok(path)
}
