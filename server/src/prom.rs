//! The Prometheus text exposition format (version 0.0.4), the one writer of `/metrics`: a
//! [`Family`] writes a metric's `# HELP` and `# TYPE` lines and then its samples, a [`Histogram`]
//! counts observations into fixed buckets and writes them cumulatively with their sum and count.
//! The live service's counters (`crate::metrics`), the GCS link's (`crate::gcs::metrics`), the
//! guidance loop's and the recorder's ([`harrier_recording::writer::RecorderStats`]) all write
//! through it. A leaf module: it imports nothing from the crate.

use std::fmt::{Display, Write as _};

/// A metric's type (the `# TYPE` line).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Only goes up (restarts at 0 with the process).
    Counter,
    /// Goes up and down.
    Gauge,
    /// Cumulative buckets, a sum and a count ([`Histogram`]).
    Histogram,
}

impl Kind {
    /// The `# TYPE` word.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Counter => "counter",
            Self::Gauge => "gauge",
            Self::Histogram => "histogram",
        }
    }
}

/// One metric family being written into a text: its `# HELP` and `# TYPE` lines are out when it
/// is made, each [`sample`](Self::sample) adds a line `name{label="value",…} value`.
#[derive(Debug)]
pub struct Family<'a> {
    out: &'a mut String,
    name: &'a str,
}

impl<'a> Family<'a> {
    /// Writes the `# HELP` and `# TYPE` lines of `name` into `out`.
    pub fn new(out: &'a mut String, name: &'a str, kind: Kind, help: &str) -> Self {
        let _ = writeln!(out, "# HELP {name} {}", escape(help, false));
        let _ = writeln!(out, "# TYPE {name} {}", kind.as_str());
        Self { out, name }
    }

    /// A counter family.
    pub fn counter(out: &'a mut String, name: &'a str, help: &str) -> Self {
        Self::new(out, name, Kind::Counter, help)
    }

    /// A gauge family.
    pub fn gauge(out: &'a mut String, name: &'a str, help: &str) -> Self {
        Self::new(out, name, Kind::Gauge, help)
    }

    /// A sample with `labels` (name, value), in that order.
    pub fn sample(&mut self, labels: &[(&str, &dyn Display)], value: impl Display) -> &mut Self {
        sample(self.out, self.name, "", labels, value);
        self
    }

    /// A sample without labels.
    pub fn value(&mut self, value: impl Display) -> &mut Self {
        self.sample(&[], value)
    }
}

/// Writes `name{suffix}{labels} value`.
fn sample(
    out: &mut String,
    name: &str,
    suffix: &str,
    labels: &[(&str, &dyn Display)],
    value: impl Display,
) {
    let _ = write!(out, "{name}{suffix}");
    for (i, (label, v)) in labels.iter().enumerate() {
        let open = if i == 0 { "{" } else { "," };
        let _ = write!(out, "{open}{label}=\"{}\"", escape(&v.to_string(), true));
    }
    if !labels.is_empty() {
        out.push('}');
    }
    let _ = writeln!(out, " {value}");
}

/// `text` with the format's escapes: `\` and line feeds, and `"` in label values.
fn escape(text: &str, label: bool) -> std::borrow::Cow<'_, str> {
    if !text.contains(['\\', '\n', '"']) {
        return text.into();
    }
    let mut s = String::with_capacity(text.len() + 2);
    for c in text.chars() {
        match c {
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '"' if label => s.push_str("\\\""),
            c => s.push(c),
        }
    }
    s.into()
}

/// Observations counted into buckets of fixed upper bounds: rendered as `name_bucket{le="…"}`
/// (cumulative, then `+Inf`), `name_sum` and `name_count`.
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram {
    /// Upper bounds of the buckets, ascending.
    bounds: &'static [f64],
    /// Observations per bucket (not cumulative); those above every bound are only in `count`.
    counts: Vec<u64>,
    count: u64,
    sum: f64,
}

impl Histogram {
    /// An empty histogram over `bounds` (ascending upper bounds).
    pub fn new(bounds: &'static [f64]) -> Self {
        Self {
            bounds,
            counts: vec![0; bounds.len()],
            count: 0,
            sum: 0.0,
        }
    }

    /// Counts `v`.
    pub fn observe(&mut self, v: f64) {
        if let Some(i) = self.bounds.iter().position(|&b| v <= b) {
            self.counts[i] += 1;
        }
        self.count += 1;
        self.sum += v;
    }

    /// Writes the family `name` with `help`.
    pub fn render(&self, out: &mut String, name: &str, help: &str) {
        Family::new(out, name, Kind::Histogram, help);
        let mut cumulative = 0;
        for (b, n) in self.bounds.iter().zip(&self.counts) {
            cumulative += n;
            sample(out, name, "_bucket", &[("le", b)], cumulative);
        }
        sample(out, name, "_bucket", &[("le", &"+Inf")], self.count);
        sample(out, name, "_sum", &[], self.sum);
        sample(out, name, "_count", &[], self.count);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn families_and_histograms_in_the_text_format() {
        let mut out = String::new();
        Family::counter(&mut out, "x_total", "Things, by kind.")
            .sample(&[("kind", &"a"), ("n", &7)], 3)
            .sample(&[("kind", &"q\"\\\n")], 0.5);
        Family::gauge(&mut out, "y", "A level.").value(-1.25);
        Family::gauge(&mut out, "empty", "No samples.");
        let mut h = Histogram::new(&[0.1, 1.0]);
        for v in [0.0625, 0.25, 0.5, 7.0] {
            h.observe(v);
        }
        h.render(&mut out, "z_seconds", "Waits.");
        assert_eq!(
            out,
            "# HELP x_total Things, by kind.\n# TYPE x_total counter\n\
             x_total{kind=\"a\",n=\"7\"} 3\nx_total{kind=\"q\\\"\\\\\\n\"} 0.5\n\
             # HELP y A level.\n# TYPE y gauge\ny -1.25\n\
             # HELP empty No samples.\n# TYPE empty gauge\n\
             # HELP z_seconds Waits.\n# TYPE z_seconds histogram\n\
             z_seconds_bucket{le=\"0.1\"} 1\nz_seconds_bucket{le=\"1\"} 3\n\
             z_seconds_bucket{le=\"+Inf\"} 4\nz_seconds_sum 7.8125\nz_seconds_count 4\n"
        );
    }
}
