//! Why a guidance simulation could not run: a leaf every part of the simulation imports.

/// Why a simulation could not run or its output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// Bad option.
    #[error("{0}")]
    Setup(String),
    /// Output failure.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// Plotting failure.
    #[error("plot: {0}")]
    Plot(String),
}
