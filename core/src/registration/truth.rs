//! `bias_truth.csv` (FORMAT-REGISTRATION.md §3): the sensors' true bias terms over time, what
//! scoring compares `bias_est` with. Estimators never read it.

use std::collections::BTreeMap;

use super::model::Term;
use crate::scenario::{FormatError, ScenarioFile, err, finite_cell, header_columns};

/// The true bias terms of a scenario's sensors: for each `(sensor, term)` its values over time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BiasTruth {
    series: BTreeMap<(String, Term), Vec<(f64, f64)>>,
}

impl BiasTruth {
    /// Parses `bias_truth.csv`: header `t,sensor,term,value`, rows sorted by `t`, `term` one of
    /// [`Term::name`]'s names.
    pub fn parse(text: &str) -> Result<Self, FormatError> {
        let f = ScenarioFile::BiasTruth;
        let mut lines = text.lines().enumerate();
        let header: Vec<&str> = match lines.next() {
            Some((_, h)) => h.split(',').map(str::trim).collect(),
            None => {
                return Err(err(
                    f,
                    Some(1),
                    "empty file: expected header t,sensor,term,value",
                ));
            }
        };
        let ([ct, cs, cterm, cv], _) =
            header_columns(&header, ["t", "sensor", "term", "value"], f)?;
        let mut series: BTreeMap<(String, Term), Vec<(f64, f64)>> = BTreeMap::new();
        let mut last_t = f64::NEG_INFINITY;
        for (i, line) in lines {
            let ln = i + 1;
            if line.trim().is_empty() {
                continue;
            }
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            let cell = |c: usize, name: &str| {
                cells
                    .get(c)
                    .copied()
                    .ok_or_else(|| err(f, Some(ln), format!("missing column {name:?}")))
            };
            let t = finite_cell(cell(ct, "t")?, "t", f, ln)?;
            if t < last_t {
                return Err(err(f, Some(ln), "rows are not sorted by t"));
            }
            last_t = t;
            let name = cell(cterm, "term")?;
            let term = Term::parse(name)
                .ok_or_else(|| err(f, Some(ln), format!("unknown term {name:?}")))?;
            let value = finite_cell(cell(cv, "value")?, "value", f, ln)?;
            series
                .entry((cell(cs, "sensor")?.to_string(), term))
                .or_default()
                .push((t, value));
        }
        Ok(Self { series })
    }

    /// The true value of `sensor`'s `term` at `t`: the last row at or before `t` (within 1 µs),
    /// 0 when the file has no row of it (an unbiased term).
    pub fn at(&self, sensor: &str, term: Term, t: f64) -> f64 {
        let Some(rows) = self.series.get(&(sensor.to_string(), term)) else {
            return 0.0;
        };
        let i = rows.partition_point(|(rt, _)| *rt <= t + 1e-6);
        rows.get(i.max(1) - 1).map_or(0.0, |r| r.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_looks_up_and_names_bad_lines() {
        let b = BiasTruth::parse(
            "t,sensor,term,value\n0,radar1,offset0,40\n0,radar1,scale0,0.002\n1,radar1,offset0,41\n",
        )
        .unwrap();
        assert_eq!(b.at("radar1", Term::Offset(0), 0.5), 40.0);
        assert_eq!(b.at("radar1", Term::Offset(0), 1.0), 41.0);
        assert_eq!(b.at("radar1", Term::Scale(0), 7.0), 0.002);
        assert_eq!(b.at("radar1", Term::Offset(1), 1.0), 0.0);
        assert_eq!(b.at("cam1", Term::TimeOffset, 1.0), 0.0);
        let e = BiasTruth::parse("t,sensor,term,value\n0,r,offset9,1\n").unwrap_err();
        assert_eq!((e.file, e.line), (ScenarioFile::BiasTruth, Some(2)));
        let e =
            BiasTruth::parse("t,sensor,term,value\n1,r,offset0,1\n0,r,offset0,1\n").unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(BiasTruth::parse("t,sensor,value\n").is_err());
        assert!(BiasTruth::parse("t,sensor,term,value\n0,r,offset0,nan\n").is_err());
    }
}
