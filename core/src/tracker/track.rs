//! The track and what the associators share of it: a [`Track`] with its [`TrackStatus`], and the
//! [`DetectionModel`] the soft and multi-scan associators assume. The multi-target tracker
//! (`multi`) and the MHT (`mht`) both build on these, so neither imports the other for them.

use crate::{EstimationError, Result};

/// What the soft and multi-scan associators assume of the sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectionModel {
    /// `P_D`: probability that a sensor's scan detects a target (in its field of view).
    pub pd: f64,
    /// Clutter density `ρ` in the sensor's measurement space (detections per unit of measurement
    /// volume, e.g. per m² for planar `position` sensors); `None`: estimated per cluster from the
    /// scan (the detections in the gates beyond the expected target detections, over the gates'
    /// volume).
    pub clutter_density: Option<f64>,
}

impl DetectionModel {
    /// Checked: `P_D` in (0, 1), a given density finite and > 0.
    pub fn new(pd: f64, clutter_density: Option<f64>) -> Result<Self> {
        if !(pd > 0.0 && pd < 1.0) || clutter_density.is_some_and(|r| !(r > 0.0 && r.is_finite())) {
            return Err(EstimationError::InvalidParameter(format!(
                "detection model needs P_D in (0, 1) and a clutter density > 0, got {pd}, \
                 {clutter_density:?}"
            )));
        }
        Ok(Self {
            pd,
            clutter_density,
        })
    }
}

/// Life-cycle stage of a track.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackStatus {
    /// Started by an unassociated detection, not yet confirmed by the M-of-N rule.
    Tentative,
    /// Confirmed: reported.
    Confirmed,
}

/// One track: a stable id, its filter state and its hit/miss record.
#[derive(Debug, Clone, PartialEq)]
pub struct Track<S> {
    /// Stable id, unique over the tracker's life (never reused).
    pub id: u64,
    /// Filter state after the last scan.
    pub state: S,
    /// Tentative or confirmed.
    pub status: TrackStatus,
    /// Scans since initiation, including the initiating one.
    pub scans: u32,
    /// Scans with an associated detection.
    pub hits: u32,
    /// Consecutive scans without a detection, up to the last one.
    pub consecutive_misses: u32,
    /// Time of the last associated detection (s).
    pub last_update: f64,
    /// Probability that the track follows a real target (JIPDA, MHT); `None` under GNN.
    pub existence: Option<f64>,
}
