//! Writing an MBTiles file: [`MbTilesWriter`] fills a temporary file beside the target in one
//! transaction and renames it into place at [`MbTilesWriter::finish`], so that a reader never
//! sees half a file and a failed run leaves none.

use std::path::{Path, PathBuf};

use rusqlite::Connection;

use crate::error::TilesError;
use crate::mercator::TileId;

/// SQLite's `application_id` of MBTiles files ("MPBX", MBTiles 1.3).
pub const APPLICATION_ID: i32 = 0x4d50_4258;

/// A new MBTiles file being written.
#[derive(Debug)]
pub struct MbTilesWriter {
    /// Taken by `finish`.
    conn: Option<Connection>,
    partial: PathBuf,
    path: PathBuf,
}

impl MbTilesWriter {
    /// Starts writing `path`: refuses an existing file unless `overwrite`. The tiles go to
    /// `path.partial-PID` until [`finish`](Self::finish).
    pub fn create(path: &Path, overwrite: bool) -> Result<Self, TilesError> {
        if path.exists() && !overwrite {
            return Err(TilesError::file(
                path,
                "already exists (overwrite it with --force)",
            ));
        }
        let mut partial = path.as_os_str().to_owned();
        partial.push(format!(".partial-{}", std::process::id()));
        let partial = PathBuf::from(partial);
        let _ = std::fs::remove_file(&partial);
        let conn = Connection::open(&partial)
            .map_err(|e| TilesError::file(&partial, format!("cannot create it: {e}")))?;
        conn.execute_batch(&format!(
            "PRAGMA application_id = {APPLICATION_ID};
             PRAGMA journal_mode = OFF;
             PRAGMA synchronous = OFF;
             CREATE TABLE metadata (name TEXT NOT NULL, value TEXT NOT NULL);
             CREATE UNIQUE INDEX metadata_name ON metadata (name);
             CREATE TABLE tiles (zoom_level INTEGER NOT NULL, tile_column INTEGER NOT NULL,
                                 tile_row INTEGER NOT NULL, tile_data BLOB NOT NULL);
             CREATE UNIQUE INDEX tile_index ON tiles (zoom_level, tile_column, tile_row);
             BEGIN;"
        ))
        .map_err(TilesError::sql(&partial))?;
        Ok(Self {
            conn: Some(conn),
            partial,
            path: path.to_owned(),
        })
    }

    /// Sets a metadata entry (replacing one of the same name).
    pub fn set_metadata(&mut self, name: &str, value: &str) -> Result<(), TilesError> {
        self.conn()
            .prepare_cached("INSERT OR REPLACE INTO metadata (name, value) VALUES (?1, ?2)")
            .and_then(|mut q| q.execute((name, value)))
            .map(drop)
            .map_err(TilesError::sql(&self.partial))
    }

    /// Adds the tile at XYZ address `id` (stored at its TMS row), replacing one already there.
    pub fn insert(&mut self, id: TileId, data: &[u8]) -> Result<(), TilesError> {
        self.conn()
            .prepare_cached(
                "INSERT OR REPLACE INTO tiles (zoom_level, tile_column, tile_row, tile_data) \
                 VALUES (?1, ?2, ?3, ?4)",
            )
            .and_then(|mut q| q.execute((id.z, id.x, id.tms_row(), data)))
            .map(drop)
            .map_err(TilesError::sql(&self.partial))
    }

    /// Commits, closes and renames the file into place; returns its path.
    pub fn finish(mut self) -> Result<PathBuf, TilesError> {
        let partial = self.partial.clone();
        let conn = self
            .conn
            .take()
            .ok_or_else(|| TilesError::file(&partial, "finished twice"))?;
        conn.execute_batch("COMMIT")
            .map_err(TilesError::sql(&partial))?;
        conn.close()
            .map_err(|(_, e)| TilesError::sql(&partial)(e))?;
        std::fs::rename(&partial, &self.path).map_err(|e| {
            TilesError::file(
                &self.path,
                format!("cannot move {} there: {e}", partial.display()),
            )
        })?;
        Ok(self.path.clone())
    }

    /// The open connection (until `finish`).
    fn conn(&self) -> &Connection {
        self.conn
            .as_ref()
            .expect("the connection is open until finish")
    }
}

impl Drop for MbTilesWriter {
    /// An unfinished file is removed (`finish` moved it away already).
    fn drop(&mut self) {
        if let Some(conn) = self.conn.take() {
            drop(conn);
            let _ = std::fs::remove_file(&self.partial);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_existing_file_is_kept_unless_overwritten_and_a_dropped_writer_leaves_nothing() {
        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("a.mbtiles");
        std::fs::write(&path, "keep me").expect("write");
        let e = MbTilesWriter::create(&path, false).expect_err("refused");
        assert!(e.to_string().contains("already exists"), "{e}");
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "keep me");
        let w = MbTilesWriter::create(&path, true).expect("create");
        drop(w);
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "keep me");
        assert_eq!(std::fs::read_dir(dir.path()).expect("ls").count(), 1);
        let mut w = MbTilesWriter::create(&path, true).expect("create");
        w.set_metadata("format", "png").expect("meta");
        w.insert(TileId::new(0, 0, 0).expect("tile"), b"\x89PNG\r\n\x1a\n")
            .expect("insert");
        assert_eq!(w.finish().expect("finish"), path);
        let conn = Connection::open(&path).expect("open");
        let app: i32 = conn
            .query_row("PRAGMA application_id", [], |r| r.get(0))
            .expect("id");
        assert_eq!(app, APPLICATION_ID);
        assert_eq!(std::fs::read_dir(dir.path()).expect("ls").count(), 1);
    }
}
