//! The multi-target extension of `gcs-scenario/1` (`FORMAT-MULTI.md`): several targets in
//! `scenario.json` (`targets`, `detection`), unlabeled detections (clutter included) in
//! `measurements.jsonl`, a `target` column in `truth.csv`.
//!
//! Single-target readers still read such a scenario (the extension only adds keys and a column);
//! this module reads it as a sequence of scans with the single-target parsers of
//! [`crate::scenario`] underneath.

use std::collections::BTreeMap;

use serde::Deserialize;

pub use crate::scenario::{DetectionSpec, Region};
use crate::scenario::{
    FormatError, Measurement, Scenario, ScenarioFile, Target, TruthRow, err, finite_cell,
    header_columns, parse_measurements,
};

/// The keys the extension adds to `scenario.json`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
struct MultiKeys {
    targets: Vec<Target>,
}

/// One scan: the time and every detection of that time (all sensors), unlabeled.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// Scan time (s).
    pub t: f64,
    /// Detections with finite `z`, in file order.
    pub detections: Vec<Measurement>,
}

/// A parsed multi-target scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiScenario {
    /// `scenario.json` as the single-target reader sees it.
    pub scenario: Scenario,
    /// `targets`.
    pub targets: Vec<Target>,
    /// `detection`, when given.
    pub detection: Option<DetectionSpec>,
    /// One scan per time `t0 + k·dt ≤ t_end`, empty scans included.
    pub scans: Vec<Scan>,
    /// `truth.csv` per target (index into `targets`), when present.
    pub truth: Option<Vec<Vec<TruthRow>>>,
    /// Detections skipped because a component was NaN/null.
    pub skipped_nonfinite: usize,
}

impl MultiScenario {
    /// Parses the three files of a multi-target scenario.
    pub fn parse(
        scenario_json: &str,
        measurements_jsonl: &str,
        truth_csv: Option<&str>,
    ) -> Result<Self, FormatError> {
        let f = ScenarioFile::Scenario;
        let scenario = Scenario::parse(scenario_json)?;
        let keys: MultiKeys = serde_json::from_str(scenario_json)
            .map_err(|e| err(f, Some(e.line()), format!("multi-target keys: {e}")))?;
        if keys.targets.is_empty() {
            return Err(err(f, None, "targets is empty"));
        }
        let mut ids: Vec<&str> = keys.targets.iter().map(|t| t.id.as_str()).collect();
        ids.sort_unstable();
        if ids.windows(2).any(|w| w[0] == w[1]) {
            return Err(err(f, None, "target ids in targets are not unique"));
        }
        if let Some(d) = &scenario.detection {
            let ok = d.pd > 0.0 && d.pd <= 1.0 && d.clutter_rate >= 0.0;
            if !ok {
                return Err(err(
                    f,
                    None,
                    "detection.pd must be in (0, 1] and clutter_rate ≥ 0",
                ));
            }
        }
        let measurements = parse_measurements(measurements_jsonl, &scenario)?;
        let (scans, skipped_nonfinite) =
            scans_on_grid(&scenario, measurements_jsonl, measurements)?;
        let truth = truth_csv
            .map(|text| parse_multi_truth(text, &keys.targets))
            .transpose()?;
        Ok(Self {
            detection: scenario.detection.clone(),
            scenario,
            targets: keys.targets,
            scans,
            truth,
            skipped_nonfinite,
        })
    }

    /// Truths alive at scan time `t` (a row within 1 µs): `(target index, canonical state)`.
    pub fn truth_at(&self, t: f64) -> Vec<(usize, [f64; 6])> {
        let Some(truth) = &self.truth else {
            return Vec::new();
        };
        truth
            .iter()
            .enumerate()
            .filter_map(|(i, rows)| {
                let k = rows.partition_point(|r| r.t < t - 1e-6);
                rows.get(k)
                    .filter(|r| (r.t - t).abs() <= 1e-6)
                    .map(|r| (i, r.state))
            })
            .collect()
    }
}

/// Sorts the detections into the scan grid `t0 + k·dt`; a detection off the grid is an error.
fn scans_on_grid(
    sc: &Scenario,
    text: &str,
    measurements: Vec<Measurement>,
) -> Result<(Vec<Scan>, usize), FormatError> {
    let f = ScenarioFile::Measurements;
    let (t0, dt) = (sc.time.t0, sc.time.dt);
    let n = ((sc.time.t_end - t0) / dt + 1e-9).floor();
    if !(0.0..1e7).contains(&n) {
        return Err(err(
            ScenarioFile::Scenario,
            None,
            "time.t_end must be ≥ t0 and give fewer than 10⁷ scans",
        ));
    }
    let mut scans: Vec<Scan> = (0..=n as usize)
        .map(|k| Scan {
            t: t0 + k as f64 * dt,
            detections: Vec::new(),
        })
        .collect();
    // Line numbers of the non-empty lines, in the order parse_measurements returned them.
    let lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, _)| i + 1);
    let mut skipped = 0;
    for (m, ln) in measurements.into_iter().zip(lines) {
        let k = ((m.t - t0) / dt).round();
        let on_grid = k >= 0.0 && (m.t - (t0 + k * dt)).abs() <= 1e-6;
        let Some(scan) = scans.get_mut(k as usize).filter(|_| on_grid) else {
            return Err(err(
                f,
                Some(ln),
                format!(
                    "t = {} is not a scan time t0 + k·dt within [t0, t_end]",
                    m.t
                ),
            ));
        };
        if m.is_finite() {
            scan.detections.push(m);
        } else {
            skipped += 1;
        }
    }
    Ok((scans, skipped))
}

/// Parses a multi-target `truth.csv` (header `t,target,x,y,z,vx,vy,vz,mode`): rows per target, in
/// the order of `targets`.
pub fn parse_multi_truth(
    text: &str,
    targets: &[Target],
) -> Result<Vec<Vec<TruthRow>>, FormatError> {
    let f = ScenarioFile::Truth;
    let mut lines = text.lines().enumerate();
    let header: Vec<&str> = match lines.next() {
        Some((_, h)) => h.split(',').map(str::trim).collect(),
        None => return Err(err(f, Some(1), "empty file: expected a header")),
    };
    let names = ["t", "target", "x", "y", "z", "vx", "vy", "vz"];
    let (col, mode_col) = header_columns(&header, names, f)?;
    let index: BTreeMap<&str, usize> = targets
        .iter()
        .enumerate()
        .map(|(i, t)| (t.id.as_str(), i))
        .collect();
    let mut out = vec![Vec::<TruthRow>::new(); targets.len()];
    let mut last_t = f64::NEG_INFINITY;
    for (i, line) in lines {
        let ln = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let cell = |k: usize| {
            cells
                .get(col[k])
                .copied()
                .ok_or_else(|| err(f, Some(ln), format!("missing column {:?}", names[k])))
        };
        let id = cell(1)?;
        let &ti = index
            .get(id)
            .ok_or_else(|| err(f, Some(ln), format!("target {id:?} is not in targets")))?;
        let mut v = [0.0; 7];
        for (slot, k) in v.iter_mut().zip([0, 2, 3, 4, 5, 6, 7]) {
            let c = cell(k)?;
            *slot = finite_cell(c, names[k], f, ln)?;
        }
        if v[0] < last_t {
            return Err(err(f, Some(ln), "rows are not sorted by t"));
        }
        last_t = v[0];
        out[ti].push(TruthRow {
            t: v[0],
            state: [v[1], v[2], v[3], v[4], v[5], v[6]],
            mode: mode_col
                .and_then(|c| cells.get(c))
                .map(|s| (*s).to_string())
                .unwrap_or_default(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::ScenarioData;

    const SC: &str = r#"{"format":"gcs-scenario/1","name":"m","dims":2,"plane_z":0,
 "time":{"t0":0,"dt":1,"t_end":3},"target":{"id":"multi"},
 "targets":[{"id":"a"},{"id":"b"}],
 "detection":{"pd":0.9,"clutter_rate":2,"region":{"min":[-10,-10],"max":[10,10]}},
 "sensors":[{"id":"s","platform":"p","kind":"position","ncomp":2,"noise":{"type":"gaussian","std":[1,1]}}]}"#;

    fn line(t: f64, x: f64) -> String {
        format!(
            r#"{{"t":{t},"sensor":"s","kind":"position","platform":{{"pos":[0,0,0]}},"z":[{x},0]}}"#
        )
    }

    #[test]
    fn parses_scans_and_truth() {
        let meas = [line(0.0, 1.0), line(0.0, 2.0), line(2.0, 3.0)].join("\n");
        let truth =
            "t,target,x,y,z,vx,vy,vz,mode\n0,a,1,0,0,1,0,0,\n1,a,2,0,0,1,0,0,\n1,b,5,0,0,0,0,0,\n";
        let m = MultiScenario::parse(SC, &meas, Some(truth)).unwrap();
        assert_eq!(m.targets.len(), 2);
        assert_eq!(m.detection.as_ref().unwrap().region.unwrap().area(), 400.0);
        let counts: Vec<_> = m.scans.iter().map(|s| (s.t, s.detections.len())).collect();
        assert_eq!(counts, vec![(0.0, 2), (1.0, 0), (2.0, 1), (3.0, 0)]);
        assert_eq!(m.truth_at(0.0).len(), 1);
        let at1 = m.truth_at(1.0);
        assert_eq!(at1.iter().map(|(i, _)| *i).collect::<Vec<_>>(), vec![0, 1]);
        assert_eq!(at1[1].1[0], 5.0);
        // The single-target reader still reads the same files.
        assert!(ScenarioData::parse(SC, &meas, Some(truth)).is_ok());
    }

    #[test]
    fn errors_name_the_file_and_line() {
        let meas = [line(0.0, 1.0), line(0.5, 2.0)].join("\n");
        let e = MultiScenario::parse(SC, &meas, None).unwrap_err();
        assert_eq!((e.file, e.line), (ScenarioFile::Measurements, Some(2)));
        let e = MultiScenario::parse(SC, "", Some("t,target,x,y,z,vx,vy,vz\n0,c,0,0,0,0,0,0\n"))
            .unwrap_err();
        assert_eq!((e.file, e.line), (ScenarioFile::Truth, Some(2)));
        let e = MultiScenario::parse(&SC.replace(r#"{"id":"b"}"#, r#"{"id":"a"}"#), "", None)
            .unwrap_err();
        assert!(e.message.contains("unique"));
        let e =
            MultiScenario::parse(&SC.replace("\"targets\"", "\"targetz\""), "", None).unwrap_err();
        assert_eq!(e.file, ScenarioFile::Scenario);
    }
}
