//! The time of day as both sides put it on the wire: UNIX time in seconds (`time_unix` of a
//! detection scan and a truth sample, TIMESYNC answers). The one function in the workspace that
//! reads the system clock for that: the simulator stamps with it, the server
//! (harrier-server's `clock`, which adds what it knows of the sources' clocks) and its recording
//! read arrival times with it.

/// Now as UNIX time (s); 0 if the system clock is before 1970.
pub fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}
