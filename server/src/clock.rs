//! The server's clock: the one function that reads the time of day, for the live service
//! (`live::clock`, which adds what it knows of the sources' clocks) and the recording alike.

/// Now as UNIX time (s).
pub fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}
