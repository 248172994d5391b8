//! The road constraint of \[CIMM\] §3.1 as a pseudo-measurement ([`RoadConstraint`]).

use nalgebra::{Matrix2, SMatrix, SVector, Vector2};

use super::network::Road;
use crate::measurement::MeasurementModel;

/// The road pseudo-measurement of \[CIMM\] §3.1 for a CV-layout state (`[p; v]`, planar or 3-D):
/// `h_r(x) = [offset(p), n(p)·v]`, measured as `z^r = [0, 0]` with noise
/// `diag(sigma_m², sigma_v²)`: the target is on the centre line (lateral offset 0, std `sigma_m`)
/// and moves along its tangent (normal velocity 0, std `sigma_v`).
#[derive(Debug, Clone, Copy)]
pub struct RoadConstraint<'a> {
    road: &'a Road,
    r: Matrix2<f64>,
}

impl<'a> RoadConstraint<'a> {
    /// Constraint to `road` with its `sigma_m` and normal-velocity std `sigma_v` (m/s, > 0).
    pub fn new(road: &'a Road, sigma_v: f64) -> Self {
        let s = road.sigma_m();
        Self {
            road,
            r: Matrix2::new(s * s, 0.0, 0.0, sigma_v * sigma_v),
        }
    }

    /// The pseudo-measurement value `z^r = [0, 0]`.
    pub fn z() -> Vector2<f64> {
        Vector2::zeros()
    }

    fn split<const N: usize>(x: &SVector<f64, N>) -> (Vector2<f64>, Vector2<f64>) {
        let d = N / 2;
        (Vector2::new(x[0], x[1]), Vector2::new(x[d], x[d + 1]))
    }
}

impl<const N: usize> MeasurementModel<N, 2> for RoadConstraint<'_> {
    fn function(&self, x: &SVector<f64, N>) -> Vector2<f64> {
        let (p, v) = Self::split(x);
        let rp = self.road.project(&p);
        Vector2::new(rp.offset, rp.normal.dot(&v))
    }
    fn jacobian(&self, x: &SVector<f64, N>) -> SMatrix<f64, 2, N> {
        let (p, v) = Self::split(x);
        let rp = self.road.project(&p);
        let d = N / 2;
        let dv = rp.normal_jacobian.transpose() * v;
        let mut j = SMatrix::<f64, 2, N>::zeros();
        j[(0, 0)] = rp.normal.x;
        j[(0, 1)] = rp.normal.y;
        j[(1, 0)] = dv.x;
        j[(1, 1)] = dv.y;
        j[(1, d)] = rp.normal.x;
        j[(1, d + 1)] = rp.normal.y;
        j
    }
    fn covar(&self) -> Matrix2<f64> {
        self.r
    }
}
