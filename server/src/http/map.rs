//! `GET /map` (under `/api/v1`): the map's tile sources and the frame's origin, for the page's
//! geographic view; `GET /tiles/{z}/{x}/{y}` (at the root, like the dashboard it serves): a tile
//! of `map.mbtiles`, as stored ([`crate::map`]).

use std::sync::Arc;

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use harrier_tiles::TileId;
use harrier_tiles::mercator::MAX_ZOOM;
use utoipa::OpenApi;

use super::error::{ApiError, ErrorBody};
use super::extract::AppPath;
use super::state::ApiState;
use crate::map::{MapBody, MapService, TileError};

/// How long a browser may keep a tile without asking again (s). The file is opened once per
/// start; a changed file comes with a restart, and the `ETag` settles what a cache holds.
const MAX_AGE_S: u32 = 3600;

/// The route of this file under `/api/v1`.
pub(super) fn routes() -> Router<ApiState> {
    Router::new().route("/map", get(map))
}

/// The route of this file at the root.
pub(super) fn root_routes() -> Router<ApiState> {
    Router::new().route("/tiles/{z}/{x}/{y}", get(tile))
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(map, tile))]
pub(super) struct Doc;

/// The map: its tile sources (an online URL template, the server's MBTiles file at
/// `/tiles/{z}/{x}/{y}`) with their attribution, zoom levels and area, and the WGS-84 origin of
/// the ENU frame the API's positions are in.
#[utoipa::path(get, path = "/api/v1/map", tag = "tracks",
    responses(
        (status = 200, body = MapBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn map(State(m): State<Arc<MapService>>) -> Json<MapBody> {
    Json(m.body.clone())
}

/// A tile of the server's MBTiles file (`map.mbtiles`) at its XYZ address (OpenStreetMap's
/// scheme; the file's TMS row is `2^z − 1 − y`), as stored: PNG, JPEG or WebP images, or vector
/// tiles (`application/vnd.mapbox-vector-tile`, with `Content-Encoding: gzip` when stored
/// compressed). `y` may end in an extension (`12.png`). Cached for an hour, with an `ETag`.
/// Open to every reader, like the dashboard (browsers load tiles as images, without a token).
#[utoipa::path(get, path = "/tiles/{z}/{x}/{y}", tag = "tracks",
    params(
        ("z" = u8, Path, description = "Zoom level, 0–30", minimum = 0, maximum = 30),
        ("x" = u32, Path, description = "Column from the antimeridian, below 2^z"),
        ("y" = u32, Path, description = "Row from the north, below 2^z"),
    ),
    responses(
        (status = 200, description = "The tile as stored", content(
            (Vec<u8> = "image/png"),
            (Vec<u8> = "image/jpeg"),
            (Vec<u8> = "image/webp"),
            (Vec<u8> = "application/vnd.mapbox-vector-tile"),
        )),
        (status = 304, description = "Not modified (If-None-Match)"),
        (status = 400, description = "Not a tile address", body = ErrorBody),
        (status = 404, description = "No tile there, or no map.mbtiles", body = ErrorBody),
        (status = 500, description = "The file could not be read", body = ErrorBody),
    ),
    security(()))]
async fn tile(
    State(m): State<Arc<MapService>>,
    AppPath((z, x, y)): AppPath<(String, String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let id = tile_id(&z, &x, &y)?;
    let tile = match m.tile(id).await {
        Ok(Some(t)) => t,
        Ok(None) => {
            return Err(ApiError::not_found(format!(
                "no tile {z}/{x}/{y} in map.mbtiles"
            )));
        }
        Err(e @ TileError::NoFile) => return Err(ApiError::not_found(e.to_string())),
        Err(e @ TileError::Read(_)) => return Err(ApiError::Internal(e.to_string())),
    };
    let etag = format!("\"{:016x}\"", fnv1a(&tile.data));
    let cache = format!("public, max-age={MAX_AGE_S}");
    let fresh = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|t| t.trim() == etag || t.trim() == "*"));
    m.count(fresh);
    if fresh {
        return Ok((
            StatusCode::NOT_MODIFIED,
            [(header::ETAG, etag), (header::CACHE_CONTROL, cache)],
        )
            .into_response());
    }
    let mut r = (
        [
            (header::CONTENT_TYPE, tile.format.content_type().to_owned()),
            (header::ETAG, etag),
            (header::CACHE_CONTROL, cache),
        ],
        tile.data,
    )
        .into_response();
    if tile.gzip {
        r.headers_mut()
            .insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
    }
    Ok(r)
}

/// The tile a path names: whole numbers, `y` perhaps with an extension, on the map.
fn tile_id(z: &str, x: &str, y: &str) -> Result<TileId, ApiError> {
    let row = y.split_once('.').map_or(y, |(row, _)| row);
    let parse = |s: &str| s.parse::<u32>().ok();
    let (Some(zz), Some(xx), Some(yy)) = (parse(z), parse(x), parse(row)) else {
        return Err(ApiError::bad_request(
            "path",
            format!("/tiles/{z}/{x}/{y}: expected /tiles/Z/X/Y with whole numbers"),
        ));
    };
    u8::try_from(zz)
        .ok()
        .and_then(|zz| TileId::new(zz, xx, yy))
        .ok_or_else(|| {
            ApiError::bad_request(
                "path",
                format!(
                    "/tiles/{z}/{x}/{y} is not on the map: zoom 0–{MAX_ZOOM}, x and y below 2^zoom"
                ),
            )
        })
}

/// FNV-1a, 64 bits: the tile's `ETag`.
fn fnv1a(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use axum::http::{Method, StatusCode, header};
    use harrier_tiles::writer::MbTilesWriter;
    use harrier_tiles::{MbTiles, TileId};

    use super::super::testing::{TestApp, request};
    use crate::config::Config;
    use crate::map::MapService;

    const PNG: &[u8] = b"\x89PNG\r\n\x1a\nimage data";
    const JPEG: &[u8] = &[0xff, 0xd8, 0xff, 0xe0, 1, 2, 3];
    const GZ_PBF: &[u8] = &[0x1f, 0x8b, 8, 0, 9, 9, 9];

    /// A real MBTiles file (SQLite, written as MBTiles says, TMS rows) with three tiles at
    /// zoom 14.
    fn file(dir: &Path, format: &str, tiles: &[(u32, u32, &[u8])]) -> Arc<MbTiles> {
        let path = dir.join(format!("{format}.mbtiles"));
        let mut w = MbTilesWriter::create(&path, false).expect("create");
        for (k, v) in [
            ("name", "test area"),
            ("format", format),
            ("bounds", "8.5,47.3,8.6,47.4"),
            ("minzoom", "14"),
            ("maxzoom", "14"),
            ("attribution", "© test"),
        ] {
            w.set_metadata(k, v).expect("metadata");
        }
        for &(x, y, data) in tiles {
            w.insert(TileId::new(14, x, y).expect("tile"), data)
                .expect("insert");
        }
        w.finish().expect("finish");
        Arc::new(MbTiles::open(&path).expect("open"))
    }

    fn app_with(tiles: Arc<MbTiles>) -> TestApp {
        let mut app = TestApp::new();
        app.state.map = Arc::new(MapService::new(&Config::default(), Some(tiles)));
        app
    }

    #[tokio::test]
    async fn tiles_are_served_as_stored_by_their_xyz_address() {
        let dir = tempfile::tempdir().expect("dir");
        let app = app_with(file(
            dir.path(),
            "png",
            &[(8581, 5737, PNG), (8582, 5737, JPEG)],
        ));
        // XYZ row 5737 is stored at TMS row 2^14 − 1 − 5737 = 10646.
        let conn = rusqlite::Connection::open(dir.path().join("png.mbtiles")).expect("sqlite");
        let rows: Vec<u32> = conn
            .prepare("SELECT tile_row FROM tiles")
            .and_then(|mut q| q.query_map([], |r| r.get(0))?.collect())
            .expect("rows");
        assert_eq!(rows, [10_646, 10_646]);
        let r = app.get("/tiles/14/8581/5737").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.body, PNG);
        assert_eq!(r.headers[header::CONTENT_TYPE], "image/png");
        assert_eq!(r.headers[header::CACHE_CONTROL], "public, max-age=3600");
        assert!(r.headers.get(header::CONTENT_ENCODING).is_none());
        // The extension Leaflet templates often carry is taken too; a JPEG in a PNG file is
        // served as what it is.
        let r = app.get("/tiles/14/8582/5737.jpg").await;
        assert_eq!((r.status, r.body.as_slice()), (StatusCode::OK, JPEG));
        assert_eq!(r.headers[header::CONTENT_TYPE], "image/jpeg");
        // The same tile again with its ETag: 304, no body.
        let etag = app.get("/tiles/14/8581/5737").await.headers[header::ETAG].clone();
        let mut req = request(Method::GET, "/tiles/14/8581/5737", None, None);
        req.headers_mut().insert(header::IF_NONE_MATCH, etag);
        let r = app.call(req).await;
        assert_eq!(r.status, StatusCode::NOT_MODIFIED);
        assert!(r.body.is_empty());
        // The TMS row itself is not the XYZ address: nothing there.
        let r = app.get("/tiles/14/8581/10646").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(r.error(), "no tile 14/8581/10646 in map.mbtiles");
        let metrics = String::from_utf8_lossy(&app.get("/metrics").await.body).into_owned();
        assert!(
            metrics.contains("harrier_tiles_served_total{result=\"ok\"} 3"),
            "{metrics}"
        );
        assert!(metrics.contains("harrier_tiles_served_total{result=\"not_modified\"} 1"));
        assert_eq!(app.refused("not_found", 404), 1);
    }

    #[tokio::test]
    async fn vector_tiles_keep_their_gzip_and_bad_paths_are_400() {
        let dir = tempfile::tempdir().expect("dir");
        let app = app_with(file(dir.path(), "pbf", &[(1, 2, GZ_PBF)]));
        let r = app.get("/tiles/14/1/2.pbf").await;
        assert_eq!((r.status, r.body.as_slice()), (StatusCode::OK, GZ_PBF));
        assert_eq!(
            r.headers[header::CONTENT_TYPE],
            "application/vnd.mapbox-vector-tile"
        );
        assert_eq!(r.headers[header::CONTENT_ENCODING], "gzip");
        for bad in [
            "/tiles/a/1/2",
            "/tiles/14/-1/2",
            "/tiles/14/1/2x",
            "/tiles/3/8/0",
            "/tiles/31/0/0",
            "/tiles/300/0/0",
        ] {
            let r = app.get(bad).await;
            assert_eq!(r.status, StatusCode::BAD_REQUEST, "{bad}");
            assert!(r.error().contains("/tiles/"), "{bad}: {}", r.error());
        }
        assert_eq!(app.refused("path", 400), 6);
    }

    #[tokio::test]
    async fn the_map_lists_the_sources_and_the_origin_and_no_file_means_no_tiles() {
        let app = TestApp::new();
        let body = app.get("/api/v1/map").await.json();
        assert_eq!(body["sources"], serde_json::json!([]));
        assert_eq!(body["origin"]["lat_deg"], 47.397_742);
        let r = app.get("/tiles/14/1/2").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert!(r.error().contains("no map.mbtiles"));
        let dir = tempfile::tempdir().expect("dir");
        let tiles = file(dir.path(), "png", &[(1, 2, PNG)]);
        let mut config = Config::default();
        config.map.tile_url = "http://127.0.0.1:9/{z}/{x}/{y}.png".into();
        config.map.attribution = "© local".into();
        let mut app = TestApp::new();
        app.state.map = Arc::new(MapService::new(&config, Some(tiles)));
        let body = app.get("/api/v1/map").await.json();
        let s = &body["sources"];
        assert_eq!(s[0]["kind"], "url");
        assert_eq!(s[0]["url"], "http://127.0.0.1:9/{z}/{x}/{y}.png");
        assert_eq!(s[0]["attribution"], "© local");
        assert_eq!(s[1]["kind"], "mbtiles");
        assert_eq!(s[1]["url"], "/tiles/{z}/{x}/{y}");
        assert_eq!(s[1]["name"], "test area");
        assert_eq!(s[1]["format"], "png");
        assert_eq!(s[1]["raster"], true);
        assert_eq!(s[1]["attribution"], "© test");
        assert_eq!(
            (s[1]["min_zoom"].as_u64(), s[1]["max_zoom"].as_u64()),
            (Some(14), Some(14))
        );
        assert_eq!(s[1]["bounds"], serde_json::json!([8.5, 47.3, 8.6, 47.4]));
    }
}
