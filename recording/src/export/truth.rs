//! The session's truth in the export: per target, in the session's frame and on the export's
//! time line ([`truth_by_target`]), interpolated at the scan times into `truth.csv`.

use std::collections::BTreeMap;

use harrier_core::detection::TruthSample;
use harrier_link::geo::LocalFrame;
use harrier_link::scenario_out;
use nalgebra::Vector3;

use super::times::{TIME_TOL_S, TimeLine};

/// Truth samples further apart than this (s) are not interpolated between (the target was not
/// seen, or truth was lost).
const MAX_TRUTH_GAP_S: f64 = 2.0;

/// Linear interpolation of `samples` (time, state, mode; sorted by time) at `t`: the sample
/// within [`TIME_TOL_S`], else between two samples at most [`MAX_TRUTH_GAP_S`] apart.
fn truth_at(samples: &[(f64, [f64; 6], String)], t: f64) -> Option<([f64; 6], &str)> {
    let i = samples.partition_point(|s| s.0 < t - TIME_TOL_S);
    let after = samples.get(i)?;
    if (after.0 - t).abs() <= TIME_TOL_S {
        return Some((after.1, &after.2));
    }
    let before = samples.get(i.checked_sub(1)?)?;
    if after.0 - before.0 > MAX_TRUTH_GAP_S {
        return None;
    }
    let w = (t - before.0) / (after.0 - before.0);
    let mut s = before.1;
    for (k, v) in s.iter_mut().enumerate() {
        *v += w * (after.1[k] - before.1[k]);
    }
    Some((s, &before.2))
}

/// Samples of one target: relative time, canonical state in the session's frame, mode.
pub(super) type TargetTruth = Vec<(f64, [f64; 6], String)>;

/// The truth samples per target id, in `frame`, on `line`, sorted by time (samples without a
/// time on the line are left out).
pub(super) fn truth_by_target(
    truth: &[(i64, TruthSample)],
    frame: &LocalFrame,
    line: TimeLine,
) -> BTreeMap<String, TargetTruth> {
    let mut targets: BTreeMap<String, TargetTruth> = BTreeMap::new();
    for (_, s) in truth {
        let Some(t) = line.relative(s.t, s.time_unix) else {
            continue;
        };
        let from = LocalFrame::new(s.origin);
        let rot = from.rotation_to(frame);
        for g in &s.targets {
            let p = from.enu_to_frame(frame, &Vector3::new(g.state[0], g.state[1], g.state[2]));
            let v = rot * Vector3::new(g.state[3], g.state[4], g.state[5]);
            let state = [p.x, p.y, p.z, v.x, v.y, v.z];
            targets
                .entry(g.id.clone())
                .or_default()
                .push((t, state, g.mode.clone()));
        }
    }
    for samples in targets.values_mut() {
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    targets
}

/// `truth.csv` at `times` (FORMAT-MULTI.md's with a target column when `multi`) and its rows.
pub(super) fn truth_csv(
    targets: &BTreeMap<String, TargetTruth>,
    times: &[f64],
    multi: bool,
) -> (String, u64) {
    let mut csv = String::from(if multi {
        scenario_out::MULTI_TRUTH_HEADER
    } else {
        scenario_out::TRUTH_HEADER
    });
    let mut rows = 0;
    for &t in times {
        for (id, samples) in targets {
            if let Some((s, mode)) = truth_at(samples, t) {
                scenario_out::push_truth_row(&mut csv, t, multi.then_some(id.as_str()), &s, mode);
                rows += 1;
            }
        }
    }
    (csv, rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_truth_interpolation() {
        let s = [
            (0.0, [0.0; 6], "a".into()),
            (1.0, [2.0; 6], "b".into()),
            (4.0, [0.0; 6], "c".into()),
        ];
        assert_eq!(truth_at(&s, 0.5), Some(([1.0; 6], "a")));
        assert_eq!(truth_at(&s, 1.0000001), Some(([2.0; 6], "b")));
        assert_eq!(truth_at(&s, 2.0), None, "a gap of 3 s");
        assert_eq!(truth_at(&s, -1.0), None);
    }
}
