//! Reading an MBTiles file ([MBTiles 1.3]: SQLite with a `metadata` table of name/value pairs and
//! a `tiles` table of `zoom_level`, `tile_column`, `tile_row` in the TMS scheme, `tile_data`).
//!
//! [`MbTiles::open`] opens the file read-only and checks it once (both tables there, a known
//! format, zoom levels), so that a bad file is refused at start with its name; then
//! [`MbTiles::tile`] reads one tile by its XYZ address on a connection from a small pool (SQLite
//! connections are cheap to keep and not shared between threads: callers on an async runtime
//! call it from a blocking task). Tiles are returned as stored, with their format and whether
//! they are gzip-compressed.
//!
//! [MBTiles 1.3]: https://github.com/mapbox/mbtiles-spec/blob/master/1.3/spec.md

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use rusqlite::{Connection, OpenFlags, OptionalExtension as _};

use crate::error::TilesError;
use crate::format::{TileFormat, is_gzip};
use crate::mercator::{Bounds, MAX_ZOOM, TileId};

/// Connections kept open for reuse (more may be open at once under load; the extra ones are
/// closed when returned).
const POOL_IDLE: usize = 4;

/// What the `metadata` table says, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Metadata {
    /// `name`.
    pub name: Option<String>,
    /// `format`, else the first tile's signature.
    pub format: TileFormat,
    /// `bounds`, when given and valid.
    pub bounds: Option<Bounds>,
    /// `minzoom`, else the lowest zoom level with a tile.
    pub min_zoom: u8,
    /// `maxzoom`, else the highest.
    pub max_zoom: u8,
    /// `attribution` (may hold HTML, as the specification allows).
    pub attribution: Option<String>,
    /// Every name and value as stored.
    pub entries: BTreeMap<String, String>,
}

/// A tile as stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tile {
    /// The bytes.
    pub data: Vec<u8>,
    /// What they are: their signature, else the file's `format`.
    pub format: TileFormat,
    /// They are gzip-compressed (vector tiles usually are): `Content-Encoding: gzip`.
    pub gzip: bool,
}

/// Tiles of one zoom level: how many and how many bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ZoomCount {
    /// Zoom level.
    pub zoom: u8,
    /// Tiles.
    pub tiles: u64,
    /// Bytes of tile data.
    pub bytes: u64,
}

/// An MBTiles file opened read-only.
#[derive(Debug)]
pub struct MbTiles {
    path: PathBuf,
    metadata: Metadata,
    pool: Mutex<Vec<Connection>>,
}

impl MbTiles {
    /// Opens `path` read-only and checks it: an SQLite file with a `metadata` table and a `tiles`
    /// table (or view) of the right columns, a known format (`format`, else the first tile's
    /// signature), zoom levels within 0–30. Errors name the file and what is wrong.
    pub fn open(path: &Path) -> Result<Self, TilesError> {
        if !path.is_file() {
            return Err(TilesError::file(
                path,
                if path.exists() {
                    "not a regular file"
                } else {
                    "no such file"
                },
            ));
        }
        let conn = connect(path)?;
        let metadata = read_metadata(path, &conn)?;
        Ok(Self {
            path: path.to_owned(),
            metadata,
            pool: Mutex::new(vec![conn]),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Its metadata, checked.
    pub fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    /// The tile at XYZ address `id` (its TMS row is looked up), or `None` when the file has none
    /// there. Blocks on SQLite: call it off an async runtime's worker threads.
    pub fn tile(&self, id: TileId) -> Result<Option<Tile>, TilesError> {
        let data = self.with_connection(|conn| {
            conn.prepare_cached(
                "SELECT tile_data FROM tiles \
                 WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
            )?
            .query_row((id.z, id.x, id.tms_row()), |r| r.get::<_, Vec<u8>>(0))
            .optional()
        })?;
        Ok(data.map(|data| Tile {
            format: TileFormat::sniff(&data).unwrap_or(self.metadata.format),
            gzip: is_gzip(&data),
            data,
        }))
    }

    /// Tiles and bytes per zoom level (a scan of the whole table: for `harrier tiles info`).
    pub fn counts(&self) -> Result<Vec<ZoomCount>, TilesError> {
        self.with_connection(|conn| {
            let mut q = conn.prepare(
                "SELECT zoom_level, count(*), coalesce(sum(length(tile_data)), 0) FROM tiles \
                 GROUP BY zoom_level ORDER BY zoom_level",
            )?;
            q.query_map([], |r| {
                // SQLite's integers are i64; counts and sizes are never negative.
                Ok(ZoomCount {
                    zoom: r.get(0)?,
                    tiles: r.get::<_, i64>(1)?.unsigned_abs(),
                    bytes: r.get::<_, i64>(2)?.unsigned_abs(),
                })
            })?
            .collect()
        })
    }

    /// Runs `f` on a pooled connection (a new one when all are busy).
    fn with_connection<T>(
        &self,
        f: impl FnOnce(&Connection) -> rusqlite::Result<T>,
    ) -> Result<T, TilesError> {
        let taken = self.pool.lock().map(|mut p| p.pop()).unwrap_or(None);
        let conn = match taken {
            Some(c) => c,
            None => connect(&self.path)?,
        };
        let out = f(&conn).map_err(TilesError::sql(&self.path));
        if let Ok(mut pool) = self.pool.lock()
            && pool.len() < POOL_IDLE
        {
            pool.push(conn);
        }
        out
    }
}

/// A read-only connection (no writes, no journal, no lock upgrades).
fn connect(path: &Path) -> Result<Connection, TilesError> {
    Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|e| TilesError::file(path, format!("cannot open it as SQLite: {e}")))
}

/// The `metadata` table, checked against the `tiles` table.
fn read_metadata(path: &Path, conn: &Connection) -> Result<Metadata, TilesError> {
    let not_mbtiles = |what: &str, e: rusqlite::Error| {
        TilesError::file(path, format!("not an MBTiles file ({what}: {e})"))
    };
    let entries: BTreeMap<String, String> = conn
        .prepare("SELECT name, value FROM metadata")
        .and_then(|mut q| {
            q.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?)))?
                .collect()
        })
        .map_err(|e| not_mbtiles("its metadata table", e))?;
    let (first, lowest, highest): (Option<Vec<u8>>, Option<i64>, Option<i64>) = conn
        .query_row(
            "SELECT (SELECT tile_data FROM tiles LIMIT 1), \
             (SELECT min(zoom_level) FROM tiles), (SELECT max(zoom_level) FROM tiles)",
            [],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
        )
        .map_err(|e| not_mbtiles("its tiles table", e))?;
    // The columns are checked once here, not at the first request.
    conn.prepare("SELECT zoom_level, tile_column, tile_row, tile_data FROM tiles LIMIT 0")
        .map_err(|e| not_mbtiles("its tiles table", e))?;
    let format = match entries.get("format") {
        Some(f) => TileFormat::from_metadata(f).ok_or_else(|| {
            TilesError::file(
                path,
                format!("format {f:?} is not one of png, jpg, webp, pbf"),
            )
        })?,
        None => first
            .as_deref()
            .and_then(TileFormat::sniff)
            .ok_or_else(|| {
                TilesError::file(
                    path,
                    "no format in its metadata, and no tile whose bytes say it",
                )
            })?,
    };
    let zoom = |name: &str, stored: Option<i64>| -> Result<Option<u8>, TilesError> {
        let given = entries.get(name).map(|v| {
            v.trim()
                .parse::<i64>()
                .map_err(|_| TilesError::file(path, format!("{name} {v:?} is not a whole number")))
        });
        match given.transpose()?.or(stored) {
            None => Ok(None),
            Some(z) if (0..=i64::from(MAX_ZOOM)).contains(&z) => Ok(Some(z as u8)),
            Some(z) => Err(TilesError::file(
                path,
                format!("{name} {z} is outside 0–{MAX_ZOOM}"),
            )),
        }
    };
    let min_zoom = zoom("minzoom", lowest)?;
    let max_zoom = zoom("maxzoom", highest)?;
    let (Some(min_zoom), Some(max_zoom)) = (min_zoom, max_zoom) else {
        return Err(TilesError::file(
            path,
            "no tiles, and no minzoom/maxzoom in its metadata",
        ));
    };
    if min_zoom > max_zoom {
        return Err(TilesError::file(
            path,
            format!("minzoom {min_zoom} is above maxzoom {max_zoom}"),
        ));
    }
    Ok(Metadata {
        name: entries.get("name").cloned(),
        format,
        bounds: entries.get("bounds").and_then(|b| Bounds::parse(b)),
        min_zoom,
        max_zoom,
        attribution: entries
            .get("attribution")
            .filter(|a| !a.is_empty())
            .cloned(),
        entries,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::writer::MbTilesWriter;

    const PNG: &[u8] = b"\x89PNG\r\n\x1a\nnot really";

    fn written(dir: &Path, meta: &[(&str, &str)], tiles: &[(TileId, &[u8])]) -> PathBuf {
        let path = dir.join("t.mbtiles");
        let mut w = MbTilesWriter::create(&path, true).expect("create");
        for (k, v) in meta {
            w.set_metadata(k, v).expect("metadata");
        }
        for (id, data) in tiles {
            w.insert(*id, data).expect("insert");
        }
        w.finish().expect("finish");
        path
    }

    #[test]
    fn a_tile_is_read_by_its_xyz_address_from_its_tms_row() {
        let dir = tempfile::tempdir().expect("dir");
        let id = TileId::new(3, 2, 1).expect("tile");
        let path = written(
            dir.path(),
            &[("format", "png"), ("bounds", "-10,-10,10,10")],
            &[(id, PNG)],
        );
        // Stored in TMS: row 2^3 − 1 − 1 = 6.
        let conn = Connection::open(&path).expect("open");
        let row: u32 = conn
            .query_row("SELECT tile_row FROM tiles", [], |r| r.get(0))
            .expect("row");
        assert_eq!(row, 6);
        let m = MbTiles::open(&path).expect("open");
        assert_eq!(m.metadata().format, TileFormat::Png);
        assert_eq!((m.metadata().min_zoom, m.metadata().max_zoom), (3, 3));
        assert!(m.metadata().bounds.is_some());
        let t = m.tile(id).expect("read").expect("a tile");
        assert_eq!(
            (t.data.as_slice(), t.format, t.gzip),
            (PNG, TileFormat::Png, false)
        );
        assert_eq!(
            m.tile(TileId::new(3, 2, 6).expect("tile")).expect("read"),
            None
        );
        assert_eq!(
            m.counts().expect("counts"),
            vec![ZoomCount {
                zoom: 3,
                tiles: 1,
                bytes: PNG.len() as u64
            }]
        );
    }

    #[test]
    fn vector_tiles_are_served_gzipped_as_stored() {
        let dir = tempfile::tempdir().expect("dir");
        let id = TileId::new(0, 0, 0).expect("tile");
        let gz = [0x1f, 0x8b, 8, 0, 1, 2, 3];
        let path = written(dir.path(), &[("format", "pbf")], &[(id, &gz)]);
        let t = MbTiles::open(&path)
            .expect("open")
            .tile(id)
            .expect("read")
            .expect("tile");
        assert_eq!((t.format, t.gzip), (TileFormat::Pbf, true));
    }

    #[test]
    fn a_bad_file_is_refused_with_its_name_and_why() {
        let dir = tempfile::tempdir().expect("dir");
        let check = |path: &Path, want: &str| {
            let e = MbTiles::open(path).expect_err("refused").to_string();
            assert!(e.contains(&path.display().to_string()), "{e}");
            assert!(e.contains(want), "{want}: {e}");
        };
        check(&dir.path().join("missing.mbtiles"), "no such file");
        check(dir.path(), "not a regular file");
        let text = dir.path().join("text.mbtiles");
        std::fs::write(
            &text,
            "hello, not SQLite at all, but long enough to be read as a header",
        )
        .expect("write");
        check(&text, "not an MBTiles file");
        let empty = dir.path().join("empty.mbtiles");
        Connection::open(&empty)
            .and_then(|c| c.execute_batch("CREATE TABLE metadata (name TEXT, value TEXT);"))
            .expect("sqlite");
        check(&empty, "tiles table");
        let tiff = written(dir.path(), &[("format", "tiff")], &[]);
        check(&tiff, "format \"tiff\"");
        std::fs::remove_file(&tiff).expect("rm");
        let none = written(dir.path(), &[("format", "png")], &[]);
        check(&none, "no tiles");
        std::fs::remove_file(&none).expect("rm");
        let zoom = written(dir.path(), &[("format", "png"), ("maxzoom", "40")], &[]);
        check(&zoom, "maxzoom 40");
    }
}
