//! [`TilesError`]: why an MBTiles file could not be read or written.

/// Why an MBTiles file could not be opened, read or written; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum TilesError {
    /// The file is not a usable MBTiles file (missing, not SQLite, no `tiles` table, unknown
    /// format, …).
    #[error("MBTiles file {path}: {message}")]
    File {
        /// The file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// A query failed on a file that opened.
    #[error("MBTiles file {path}: {source}")]
    Sql {
        /// The file.
        path: String,
        /// SQLite's error.
        source: rusqlite::Error,
    },
}

impl TilesError {
    pub(crate) fn file(path: &std::path::Path, message: impl Into<String>) -> Self {
        Self::File {
            path: path.display().to_string(),
            message: message.into(),
        }
    }

    pub(crate) fn sql(path: &std::path::Path) -> impl FnOnce(rusqlite::Error) -> Self + '_ {
        move |source| Self::Sql {
            path: path.display().to_string(),
            source,
        }
    }
}
