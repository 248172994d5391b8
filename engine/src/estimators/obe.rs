//! Set-membership estimators `obe` (minimum volume) and `obe-trace` (minimum trace): the optimal
//! bounding ellipsoid filter of `harrier_core::filter::Obe` on the bounded-noise linear system of
//! `scenario.linear_system` (FORMAT.md §2.1, \[ELL\]).
//!
//! Step k is the k-th distinct measurement time: the first time only updates `x0_ellipsoid` (which
//! is the set at that time), every later time predicts one step and then updates with each
//! `position` measurement at that time (`y = z`); other measurement kinds are ignored. If a time's
//! update fails (the data contradict the set), the estimator keeps its last set and the next time
//! predicts over both steps.
//!
//! Any state size 1–6 is supported. Internally the system is padded to N × N: B gets zero columns
//! (B Bᵀ, hence the noise set, is unchanged) and C zero rows whose strips `|0 − 0·x| ≤ 1` cover
//! every ellipsoid and are skipped, so one monomorphisation per N serves every W ≤ N and M ≤ N.
//!
//! Each estimate line carries `ellipsoid` = the set (in `state_dims`) and `state` = its centre in
//! the canonical layout (unlisted indices 0, or `plane_z` for z of planar scenarios), no `cov`.

use harrier_core::filter::{
    BoundedLinearMeasurement, BoundedLinearTransition, Obe, ObeCriterion, Predictor, Updater,
};
use harrier_core::measurement::MeasKind;
use harrier_core::scenario::{EllipsoidSpec, Estimate, LinearSystem, Scenario};
use harrier_core::state::Ellipsoid;
use nalgebra::{SMatrix, SVector};
use serde_json::Value;

use crate::{EngineError, EstimatorInfo, ReplayEstimator, Step, setup};

/// `obe`: minimum-volume optimal bounding ellipsoid.
pub const OBE: EstimatorInfo = EstimatorInfo {
    name: "obe",
    summary: "set-membership OBE filter, minimum-volume ellipsoids (needs linear_system; position only)",
    params: &[],
    build: |sc, _| build(sc, ObeCriterion::MinVolume),
};

/// `obe-trace`: minimum-trace optimal bounding ellipsoid.
pub const OBE_TRACE: EstimatorInfo = EstimatorInfo {
    name: "obe-trace",
    summary: "set-membership OBE filter, minimum-trace ellipsoids (needs linear_system; position only)",
    params: &[],
    build: |sc, _| build(sc, ObeCriterion::MinTrace),
};

fn build(sc: &Scenario, criterion: ObeCriterion) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    let ls = sc.linear_system.as_ref().ok_or_else(|| {
        setup("scenario.json has no linear_system (FORMAT.md §2.1); the obe estimators need one")
    })?;
    let filter = Obe::new(criterion);
    Ok(match ls.state_dims.len() {
        1 => Box::new(ObeTracker::<1>::new(sc, ls, filter)?),
        2 => Box::new(ObeTracker::<2>::new(sc, ls, filter)?),
        3 => Box::new(ObeTracker::<3>::new(sc, ls, filter)?),
        4 => Box::new(ObeTracker::<4>::new(sc, ls, filter)?),
        5 => Box::new(ObeTracker::<5>::new(sc, ls, filter)?),
        6 => Box::new(ObeTracker::<6>::new(sc, ls, filter)?),
        n => {
            return Err(setup(format!(
                "linear_system.state_dims has {n} entries; supported state sizes are 1 to 6"
            )));
        }
    })
}

/// Rows × columns of a `linear_system` matrix, checked rectangular, non-empty and finite.
fn shape_of(name: &str, rows: &[Vec<f64>]) -> Result<(usize, usize), EngineError> {
    let cols = rows.first().map_or(0, Vec::len);
    if cols == 0 || rows.iter().any(|r| r.len() != cols) {
        return Err(setup(format!(
            "linear_system.{name} must be a non-empty rectangular matrix (array of rows)"
        )));
    }
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(setup(format!(
            "linear_system.{name} has a non-finite entry"
        )));
    }
    Ok((rows.len(), cols))
}

/// Checks that `name` is `rows × cols`.
fn expect_shape(
    name: &str,
    m: &[Vec<f64>],
    rows: usize,
    cols: usize,
) -> Result<(usize, usize), EngineError> {
    let (r, c) = shape_of(name, m)?;
    if (rows, cols) != (r, c) {
        return Err(setup(format!(
            "linear_system.{name} is {r}×{c}, expected {rows}×{cols} (n = len(state_dims))"
        )));
    }
    Ok((r, c))
}

/// The matrix zero-padded to N × N.
fn padded<const N: usize>(m: &[Vec<f64>]) -> SMatrix<f64, N, N> {
    SMatrix::from_fn(|i, j| m.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0))
}

/// `w_bound = {"type": "ball", "radius": r}`.
fn ball_radius(v: &Value) -> Result<f64, EngineError> {
    let bad = || {
        setup(format!(
            "linear_system.w_bound must be {{\"type\": \"ball\", \"radius\": r >= 0}}, got {v}"
        ))
    };
    if v.get("type").and_then(Value::as_str) != Some("ball") {
        return Err(bad());
    }
    v.get("radius")
        .and_then(Value::as_f64)
        .filter(|r| r.is_finite() && *r >= 0.0)
        .ok_or_else(bad)
}

/// `v_bound = {"type": "box", "half_width": [σ₁, …, σ_M]}`.
fn box_half_width(v: &Value, m: usize) -> Result<Vec<f64>, EngineError> {
    let bad = || {
        setup(format!(
            "linear_system.v_bound must be {{\"type\": \"box\", \"half_width\": [{m} numbers > 0]}} \
             (one per row of C), got {v}"
        ))
    };
    if v.get("type").and_then(Value::as_str) != Some("box") {
        return Err(bad());
    }
    let hw: Vec<f64> = v
        .get("half_width")
        .and_then(Value::as_array)
        .ok_or_else(bad)?
        .iter()
        .map(|x| x.as_f64().filter(|s| s.is_finite() && *s > 0.0))
        .collect::<Option<_>>()
        .ok_or_else(bad)?;
    if hw.len() != m {
        return Err(bad());
    }
    Ok(hw)
}

/// Runs [`Obe`] over the `position` measurements of a scenario.
#[derive(Debug)]
struct ObeTracker<const N: usize> {
    filter: Obe,
    transition: BoundedLinearTransition<N, N>,
    measurement: BoundedLinearMeasurement<N, N>,
    /// Rows of C (components of a position measurement).
    n_meas: usize,
    /// Canonical indices of the state.
    dims: Vec<usize>,
    /// `plane_z` for planar scenarios.
    plane_z: Option<f64>,
    /// The set after the last successful step (initially `x0_ellipsoid`).
    set: Ellipsoid<N>,
    /// Time of `set` (NaN before the first step).
    t: f64,
    /// Predictions needed to bring `set` to the next step: 0 before the first step, 1 after a
    /// successful step, one more for each step whose update failed.
    due: usize,
}

impl<const N: usize> ObeTracker<N> {
    fn new(sc: &Scenario, ls: &LinearSystem, filter: Obe) -> Result<Self, EngineError> {
        let dims = ls.state_dims.clone();
        if let Some(&d) = dims.iter().find(|&&d| d >= 6) {
            return Err(setup(format!(
                "linear_system.state_dims: {d} is not a canonical index (0..5)"
            )));
        }
        if (1..dims.len()).any(|i| dims[..i].contains(&dims[i])) {
            return Err(setup(format!(
                "linear_system.state_dims {dims:?} has a repeated index"
            )));
        }
        expect_shape("A", &ls.A, N, N)?;
        let (_, w) = shape_of("B", &ls.B)?;
        expect_shape("B", &ls.B, N, w)?;
        if w > N {
            return Err(setup(format!(
                "linear_system.B has {w} columns, more than the {N} states; not supported"
            )));
        }
        let (m, _) = shape_of("C", &ls.C)?;
        expect_shape("C", &ls.C, m, N)?;
        if m > N {
            return Err(setup(format!(
                "linear_system.C has {m} rows, more than the {N} states; not supported"
            )));
        }
        let radius = ball_radius(&ls.w_bound)?;
        let hw = box_half_width(&ls.v_bound, m)?;
        let half_width = SVector::<f64, N>::from_fn(|i, _| hw.get(i).copied().unwrap_or(1.0));
        let transition = BoundedLinearTransition::new(padded(&ls.A), padded(&ls.B), radius)
            .map_err(|e| setup(format!("linear_system: {e}")))?;
        let measurement = BoundedLinearMeasurement::new(padded(&ls.C), half_width)
            .map_err(|e| setup(format!("linear_system: {e}")))?;

        let x0 = &ls.x0_ellipsoid;
        if let Some(d) = &x0.dims
            && *d != dims
        {
            return Err(setup(format!(
                "linear_system.x0_ellipsoid.dims {d:?} differ from state_dims {dims:?}"
            )));
        }
        if x0.center.len() != N {
            return Err(setup(format!(
                "linear_system.x0_ellipsoid.center has {} entries, expected {N}",
                x0.center.len()
            )));
        }
        expect_shape("x0_ellipsoid.shape", &x0.shape, N, N)?;
        let set = Ellipsoid::new(SVector::from_column_slice(&x0.center), padded(&x0.shape))
            .map_err(|e| setup(format!("linear_system.x0_ellipsoid: {e}")))?;

        Ok(Self {
            filter,
            transition,
            measurement,
            n_meas: m,
            dims,
            plane_z: (sc.dims == 2).then(|| sc.plane_z()),
            set,
            t: f64::NAN,
            due: 0,
        })
    }

    /// The set at `step` from the current one, or why not (`self` untouched).
    fn advance(&self, step: &Step<'_>) -> Result<Ellipsoid<N>, EngineError> {
        let mut set = self.set;
        for _ in 0..self.due {
            // The system is discrete (one call = one step); dt is informative only.
            set = self
                .filter
                .predict(&self.transition, &set, step.t - self.t)?;
        }
        for m in step.measurements {
            if m.kind != MeasKind::Position {
                continue;
            }
            if m.z.len() != self.n_meas {
                return Err(setup(format!(
                    "position measurement of {:?} at t = {} has {} components but \
                     linear_system.C has {} rows",
                    m.sensor,
                    m.t,
                    m.z.len(),
                    self.n_meas
                )));
            }
            let y = SVector::<f64, N>::from_fn(|i, _| m.z.get(i).copied().unwrap_or(0.0));
            set = self.filter.update(&self.measurement, &set, &y)?.state;
        }
        Ok(set)
    }

    fn estimate(&self) -> Estimate {
        let mut state = [0.0; 6];
        if let Some(z) = self.plane_z {
            state[2] = z;
        }
        for (i, &d) in self.dims.iter().enumerate() {
            state[d] = self.set.center[i];
        }
        Estimate {
            t: self.t,
            state: Some(state),
            ellipsoid: Some(EllipsoidSpec {
                center: self.set.center.iter().copied().collect(),
                shape: (0..N)
                    .map(|i| (0..N).map(|j| self.set.shape[(i, j)]).collect())
                    .collect(),
                dims: Some(self.dims.clone()),
            }),
            ..Estimate::default()
        }
    }
}

impl<const N: usize> ReplayEstimator for ObeTracker<N> {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        match self.advance(step) {
            Ok(set) => {
                self.set = set;
                self.t = step.t;
                self.due = 1;
                Ok(Some(self.estimate()))
            }
            Err(e) => {
                if matches!(e, EngineError::Estimation(_)) {
                    // The step happened even though its data were rejected.
                    self.due += 1;
                }
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::scenario::{EllipsoidSpec, LinearSystem};
    use serde_json::json;

    fn system() -> LinearSystem {
        LinearSystem {
            state_dims: vec![0, 1, 3, 4],
            A: vec![
                vec![1.0, 0.0, 0.1, 0.0],
                vec![0.0, 1.0, 0.0, 0.1],
                vec![0.0, 0.0, 1.0, 0.0],
                vec![0.0, 0.0, 0.0, 1.0],
            ],
            B: vec![
                vec![0.01, 0.0],
                vec![0.0, 0.01],
                vec![0.2, 0.0],
                vec![0.0, 0.2],
            ],
            C: vec![vec![1.0, 0.0, 0.0, 0.0], vec![0.0, 1.0, 0.0, 0.0]],
            w_bound: json!({"type": "ball", "radius": 1.0}),
            v_bound: json!({"type": "box", "half_width": [0.3, 0.3]}),
            x0_ellipsoid: EllipsoidSpec {
                center: vec![0.0, 0.0, 0.5, 0.2],
                shape: vec![
                    vec![4.0, 0.0, 0.0, 0.0],
                    vec![0.0, 4.0, 0.0, 0.0],
                    vec![0.0, 0.0, 1.0, 0.0],
                    vec![0.0, 0.0, 0.0, 1.0],
                ],
                dims: Some(vec![0, 1, 3, 4]),
            },
        }
    }

    fn scenario(ls: Option<LinearSystem>) -> Scenario {
        let mut sc: Scenario = serde_json::from_value(json!({
            "format": "gcs-scenario/1", "name": "t", "dims": 2, "plane_z": 0.0,
            "time": {"t0": 0.0, "dt": 0.1, "t_end": 1.0},
            "target": {"id": "tgt"}, "platforms": [], "sensors": []
        }))
        .unwrap();
        sc.linear_system = ls;
        sc
    }

    fn setup_error(ls: Option<LinearSystem>) -> String {
        match build(&scenario(ls), ObeCriterion::MinVolume) {
            Err(EngineError::Setup(m)) => m,
            Err(e) => panic!("not a setup error: {e}"),
            Ok(_) => panic!("accepted"),
        }
    }

    #[test]
    fn accepts_the_reference_system() {
        assert!(build(&scenario(Some(system())), ObeCriterion::MinTrace).is_ok());
    }

    #[test]
    fn rejects_missing_or_malformed_systems() {
        assert!(setup_error(None).contains("no linear_system"));
        let mut ls = system();
        ls.A.pop();
        assert!(setup_error(Some(ls)).contains("linear_system.A is 3×4"));
        let mut ls = system();
        ls.x0_ellipsoid.shape[0][0] = -1.0;
        assert!(setup_error(Some(ls)).contains("x0_ellipsoid"));
        let mut ls = system();
        ls.v_bound = json!({"type": "box", "half_width": [0.3]});
        assert!(setup_error(Some(ls)).contains("v_bound"));
        let mut ls = system();
        ls.w_bound = json!({"type": "box", "half_width": [1.0]});
        assert!(setup_error(Some(ls)).contains("w_bound"));
        let mut ls = system();
        ls.state_dims = vec![0; 7];
        assert!(setup_error(Some(ls)).contains("supported state sizes"));
    }
}
