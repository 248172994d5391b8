//! Text and file output of a run: the summary lines for stdout and the trajectories as CSV or
//! JSONL.

use std::io::Write;
use std::path::Path;

use serde::Serialize;

use super::error::SimError;
use super::types::{Summary, Trajectory};

/// The summary as text lines for stdout.
pub fn summary_lines(s: &Summary) -> Vec<String> {
    let mut out = vec![format!(
        "{}: law {}, {} UAV(s), {} s at {} Hz, estimator {}, simulated in {:.1} ms",
        s.case,
        s.law,
        s.uavs,
        s.duration,
        (1.0 / s.dt).round(),
        s.estimator,
        s.elapsed_ms
    )];
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    for u in &s.per_uav {
        out.push(format!(
            "  {}: path to circle {} m at t = {} s; height ±1 m at t = {} s (bang-bang {:.1} s), overshoot {:.2} m; standoff RMS {} m",
            u.id,
            opt(u.path_to_circle_m),
            opt(u.time_to_circle_s),
            opt(u.time_to_height_s),
            u.bang_bang_time_s,
            u.height_overshoot_m,
            opt(u.standoff_rms_m),
        ));
    }
    if let Some(o) = s.optimal_path_m {
        out.push(format!("  geometric optimum (turn + tangent): {o:.1} m"));
    }
    if let Some(e) = s.estimate_rms_m {
        out.push(format!("  target estimate RMS error: {e:.2} m"));
    }
    if let (Some(m), Some(r)) = (s.phase_max_error_deg, s.phase_rms_error_deg) {
        out.push(format!(
            "  phase spacing error (last 30 %): max {m:.2}°, RMS {r:.2}°"
        ));
    }
    if let (Some(st), Some(mx)) = (s.formation_steady_error_pct, s.formation_max_error_pct) {
        out.push(format!(
            "  commanded-range error: steady state (last 40 s) {st:.2} %, max {mx:.1} %"
        ));
    }
    if let (Some(p), Some(c)) = (s.obstacle_penetrations, s.obstacle_min_clearance_m) {
        out.push(format!(
            "  obstacle penetrations {p}, min clearance {c:.1} m"
        ));
    }
    if let (Some(a), Some(b), Some(f)) = (
        s.range_rms_straight_m,
        s.range_rms_maneuver_m,
        s.observability_factor,
    ) {
        out.push(format!(
            "  range-estimate RMS (2nd half): straight {a:.1} m, maneuver {b:.1} m, factor {f:.1}"
        ));
    }
    out.push(format!(
        "  flown: speed {:.1}–{:.1} m/s, turn rate ≤ {:.3} rad/s, |vz| ≤ {:.2} m/s, |az| ≤ {:.2} m/s² (limits {}–{} m/s, {} rad/s, {} m/s, {} m/s²)",
        s.min_speed,
        s.max_speed,
        s.max_turn_rate,
        s.max_vz,
        s.max_az,
        s.limits.v_min,
        s.limits.v_max,
        s.limits.turn_rate_max,
        s.limits.vz_max,
        s.limits.az_max
    ));
    out
}

#[derive(Serialize)]
struct Row<'a> {
    t: f64,
    id: &'a str,
    kind: &'a str,
    x: f64,
    y: f64,
    z: f64,
    vx: f64,
    vy: f64,
    vz: f64,
}

/// Writes the trajectories: JSONL when the file name ends in `.jsonl`, CSV otherwise
/// (`t,id,kind,x,y,z,vx,vy,vz`), through a temporary file renamed at the end.
pub fn write_trajectories(path: &Path, trajectories: &[Trajectory]) -> Result<(), SimError> {
    let jsonl = path.extension().is_some_and(|e| e == "jsonl");
    let io = |source| SimError::Io {
        path: path.display().to_string(),
        source,
    };
    let tmp = path.with_extension("tmp~");
    let file = std::fs::File::create(&tmp).map_err(io)?;
    let mut w = std::io::BufWriter::new(file);
    let res = (|| -> std::io::Result<()> {
        if !jsonl {
            writeln!(w, "t,id,kind,x,y,z,vx,vy,vz")?;
        }
        for tr in trajectories {
            for s in &tr.samples {
                let row = Row {
                    t: s.t,
                    id: &tr.id,
                    kind: tr.kind,
                    x: s.pos[0],
                    y: s.pos[1],
                    z: s.pos[2],
                    vx: s.vel[0],
                    vy: s.vel[1],
                    vz: s.vel[2],
                };
                if jsonl {
                    serde_json::to_writer(&mut w, &row).map_err(std::io::Error::other)?;
                    writeln!(w)?;
                } else {
                    writeln!(
                        w,
                        "{:.3},{},{},{:.3},{:.3},{:.3},{:.4},{:.4},{:.4}",
                        s.t,
                        tr.id,
                        tr.kind,
                        s.pos[0],
                        s.pos[1],
                        s.pos[2],
                        s.vel[0],
                        s.vel[1],
                        s.vel[2]
                    )?;
                }
            }
        }
        w.flush()
    })();
    match res.and_then(|()| std::fs::rename(&tmp, path)) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(io(e))
        }
    }
}
