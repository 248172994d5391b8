//! The feeds' counters: events per feed (`sent`, `dropped`, `errors`, …), rendered as one
//! Prometheus family.

use std::collections::BTreeMap;
use std::sync::{Mutex, PoisonError};

use crate::prom::Family;

/// Counts per feed and event, e.g. (`cot`, `sent`).
#[derive(Debug, Default)]
pub struct FeedCounters {
    counts: Mutex<BTreeMap<(&'static str, &'static str), u64>>,
}

impl FeedCounters {
    /// Adds `n` to the count of `event` of `feed`.
    pub fn add(&self, feed: &'static str, event: &'static str, n: u64) {
        let mut c = self.counts.lock().unwrap_or_else(PoisonError::into_inner);
        *c.entry((feed, event)).or_default() += n;
    }

    /// The count of `event` of `feed` (0 when never counted).
    pub fn get(&self, feed: &str, event: &str) -> u64 {
        let c = self.counts.lock().unwrap_or_else(PoisonError::into_inner);
        c.iter()
            .find(|((f, e), _)| *f == feed && *e == event)
            .map_or(0, |(_, n)| *n)
    }

    /// Appends the family `harrier_feed_events_total` (nothing when no feed counted anything).
    pub fn render(&self, out: &mut String) {
        let c = self.counts.lock().unwrap_or_else(PoisonError::into_inner);
        if c.is_empty() {
            return;
        }
        let mut f = Family::counter(
            out,
            "harrier_feed_events_total",
            "Events of the field-format feeds (CoT, ASTERIX, ADS-B, Foxglove) by feed and event.",
        );
        for ((feed, event), n) in c.iter() {
            f.sample(&[("feed", feed), ("event", event)], n);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_render_per_feed_and_event() {
        let c = FeedCounters::default();
        let mut out = String::new();
        c.render(&mut out);
        assert!(out.is_empty());
        c.add("cot", "sent", 2);
        c.add("cot", "sent", 3);
        c.add("asterix", "dropped", 1);
        assert_eq!(c.get("cot", "sent"), 5);
        assert_eq!(c.get("cot", "dropped"), 0);
        c.render(&mut out);
        assert!(
            out.contains("harrier_feed_events_total{feed=\"cot\",event=\"sent\"} 5"),
            "{out}"
        );
        assert!(
            out.contains("harrier_feed_events_total{feed=\"asterix\",event=\"dropped\"} 1"),
            "{out}"
        );
    }
}
