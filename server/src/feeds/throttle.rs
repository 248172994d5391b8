//! How the feeds log what goes wrong with the outside (a broken line, a full socket, a refused
//! connection): at most one line per interval, saying how many were left unlogged in between.

use std::time::{Duration, Instant};

/// At most one log line per `every` (5 s by default).
#[derive(Debug)]
pub(super) struct Throttle {
    every: Duration,
    last: Option<Instant>,
    suppressed: u64,
}

impl Default for Throttle {
    fn default() -> Self {
        Self {
            every: Duration::from_secs(5),
            last: None,
            suppressed: 0,
        }
    }
}

impl Throttle {
    /// `Some(lines suppressed since the last one)` when a line may be logged now, else `None`
    /// (and the line is counted as suppressed).
    pub(super) fn allow(&mut self) -> Option<u64> {
        let now = Instant::now();
        match self.last {
            Some(at) if now.duration_since(at) < self.every => {
                self.suppressed += 1;
                None
            }
            _ => {
                self.last = Some(now);
                Some(std::mem::take(&mut self.suppressed))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_per_interval_with_the_count_in_between() {
        let mut t = Throttle::default();
        assert_eq!(t.allow(), Some(0));
        assert_eq!(t.allow(), None);
        assert_eq!(t.allow(), None);
        t.last = Some(Instant::now() - Duration::from_secs(6));
        assert_eq!(t.allow(), Some(2));
        assert_eq!(t.allow(), None);
    }
}
