//! `--sweep`: the figures of one run per vehicle count side by side ([`sweep_lines`]), and how
//! each grows per vehicle (a least-squares line through the runs).

use super::report::Report;

/// One figure of a run, `None` when the run did not measure it.
type Figure = fn(&Report) -> Option<f64>;

/// The columns: heading, unit per vehicle for the slope line, the figure, its decimals.
const COLUMNS: [(&str, &str, Figure, usize); 12] = [
    ("scans/s", "scans/s", |r| Some(r.server.scans_per_s), 0),
    ("lost", "", |r| Some(r.server.lost as f64), 0),
    (
        "p50 ms",
        "ms",
        |r| r.websocket.as_ref().map(|w| w.latency_ms.p50),
        1,
    ),
    (
        "p99 ms",
        "ms",
        |r| r.websocket.as_ref().map(|w| w.latency_ms.p99),
        1,
    ),
    (
        "server cores",
        "cores",
        |r| {
            r.cpu
                .and_then(|c| c.server_cores.or(Some(c.measured_cores)))
        },
        3,
    ),
    (
        "RSS MiB",
        "MiB",
        |r| r.rss.start_kib.map(|k| k as f64 / 1024.0),
        1,
    ),
    (
        "RSS +MiB",
        "",
        |r| r.rss.growth_kib.map(|k| k as f64 / 1024.0),
        2,
    ),
    (
        "WS kB/s",
        "kB/s",
        |r| r.websocket.as_ref().map(|w| w.bytes_per_s / 1e3),
        1,
    ),
    (
        "of it vehicles",
        "kB/s",
        |r| r.websocket.as_ref().map(|w| w.vehicles_bytes_per_s / 1e3),
        1,
    ),
    (
        "MAVLink frames/s",
        "frames/s",
        |r| r.mavlink.as_ref().map(|m| m.frames_per_s),
        0,
    ),
    (
        "frames lost",
        "",
        |r| r.mavlink.as_ref().map(|m| m.frames_lost as f64),
        0,
    ),
    (
        "ticks ≤ 5 ms %",
        "",
        |r| {
            r.mavlink
                .as_ref()
                .and_then(|m| m.guidance.as_ref()?.within_5ms)
                .map(|x| 100.0 * x)
        },
        1,
    ),
];

/// Least-squares slope of `y` against `x` (`None` with fewer than two distinct `x`).
fn slope(points: &[(f64, f64)]) -> Option<f64> {
    let n = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let sxx: f64 = points.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    (points.len() >= 2 && sxx > 0.0).then(|| sxy / sxx)
}

/// The sweep's table: a row per run, then the growth per vehicle of each figure with a unit.
pub fn sweep_lines(reports: &[Report]) -> Vec<String> {
    let mut out = Vec::new();
    let Some(first) = reports.first() else {
        return out;
    };
    let s = &first.setup;
    // The first runs may have fewer vehicles than --assign.
    let assign = reports.iter().map(|r| r.setup.assign).max().unwrap_or(0);
    out.push(format!(
        "harrier bench --sweep: {} Hz × {} detections per vehicle{}{}; {} s measured per run; server {}",
        s.rate_hz,
        s.detections,
        s.mavlink_telemetry_hz
            .map_or(String::new(), |hz| format!(", MAVLink telemetry at {hz} Hz")),
        if assign > 0 {
            format!(", up to {assign} assigned")
        } else {
            String::new()
        },
        s.duration_s,
        s.server
    ));
    let widths: Vec<usize> = COLUMNS.iter().map(|c| c.0.chars().count().max(8)).collect();
    let mut head = format!("{:>8} {:>6}", "vehicles", "load");
    for ((name, ..), w) in COLUMNS.iter().zip(&widths) {
        head.push_str(&format!("  {name:>w$}"));
    }
    out.push(head);
    for r in reports {
        let mut row = format!(
            "{:>8} {:>6.2}",
            r.setup.vehicles,
            (r.machine.load_start + r.machine.load_end) / 2.0
        );
        for ((_, _, f, d), w) in COLUMNS.iter().zip(&widths) {
            let cell = f(r).map_or("–".to_string(), |v| format!("{v:.d$}"));
            row.push_str(&format!("  {cell:>w$}"));
        }
        out.push(row);
    }
    let mut growth = format!("{:>15}", "per vehicle");
    for ((_, unit, f, d), w) in COLUMNS.iter().zip(&widths) {
        let points: Vec<(f64, f64)> = reports
            .iter()
            .filter_map(|r| Some((f64::from(r.setup.vehicles), f(r)?)))
            .collect();
        let cell = match (unit.is_empty(), slope(&points)) {
            (false, Some(k)) => format!("{k:.prec$}", prec = d + 2),
            _ => String::new(),
        };
        growth.push_str(&format!("  {cell:>w$}"));
    }
    out.push(growth);
    out.push(
        "(load: the machine's 1-minute load average during the run; per vehicle: the least-squares \
         slope of each figure against the number of vehicles)"
            .to_string(),
    );
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_slope_of_a_line_is_its_growth() {
        let pts = [(10.0, 1.5), (50.0, 5.5), (100.0, 10.5)];
        let k = super::slope(&pts).expect("a slope");
        assert!((k - 0.1).abs() < 1e-12, "{k}");
        assert_eq!(super::slope(&[(10.0, 1.0)]), None);
        assert_eq!(super::slope(&[(10.0, 1.0), (10.0, 2.0)]), None);
    }
}
