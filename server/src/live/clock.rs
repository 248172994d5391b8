//! The server's clock: the one place the live service reads the time of day.

/// Now as UNIX time (s).
pub fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}
