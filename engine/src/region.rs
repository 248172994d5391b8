//! A track's 95 % confidence regions: the ellipse of its (x, y) and, when its covariance covers
//! z, the ellipsoid of its (x, y, z). The API sends them with every track; the Foxglove scene
//! draws them.

use harrier_core::linalg::{ellipse_axes, ellipsoid_axes};
use nalgebra::{Matrix2, Matrix3};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::TrackView;

/// χ² quantile of 0.95 for 2 degrees of freedom (the 95 % ellipse).
pub const CHI2_95_2: f64 = 5.991_464_547_107_979;
/// χ² quantile of 0.95 for 3 degrees of freedom (the 95 % ellipsoid).
pub const CHI2_95_3: f64 = 7.814_727_903_251_178;

/// The 95 % confidence ellipse of a planar position (x, y).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Ellipse {
    /// Semi-axes (m), major first.
    pub semi_axes: [f64; 2],
    /// Direction of the major axis (rad, counter-clockwise from East).
    pub angle_rad: f64,
}

/// The 95 % confidence ellipsoid of a 3-D position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Ellipsoid {
    /// Semi-axes (m), largest first.
    pub semi_axes: [f64; 3],
    /// Unit axis directions (ENU), in the order of `semi_axes`.
    pub axes: [[f64; 3]; 3],
}

/// The position block of `k`'s covariance over the state indices `dims` (`None` when absent or
/// not finite).
fn position_cov<const N: usize>(k: &TrackView, dims: [usize; N]) -> Option<[[f64; N]; N]> {
    let mut out = [[0.0; N]; N];
    for (row, &a) in out.iter_mut().zip(&dims) {
        for (o, &b) in row.iter_mut().zip(&dims) {
            *o = k.cov_at(a, b)?;
        }
    }
    Some(out)
}

impl Ellipse {
    /// The 95 % ellipse of `k`'s (x, y).
    pub fn of(k: &TrackView) -> Option<Self> {
        let c = position_cov(k, [0, 1])?;
        let m = Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]);
        let (semi_axes, angle_rad) = ellipse_axes(&(m * CHI2_95_2));
        Some(Self {
            semi_axes,
            angle_rad,
        })
    }
}

impl Ellipsoid {
    /// The 95 % ellipsoid of `k`'s (x, y, z), when its covariance covers z.
    pub fn of(k: &TrackView) -> Option<Self> {
        let c = position_cov(k, [0, 1, 2])?;
        let (semi_axes, axes) = ellipsoid_axes(&(Matrix3::from_fn(|i, j| c[i][j]) * CHI2_95_3));
        Some(Self { semi_axes, axes })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackStatus;

    /// A planar track with covariance diag(4, 1) over (x, y) and (4, 1) over (vx, vy).
    fn planar() -> TrackView {
        TrackView {
            id: 1,
            status: TrackStatus::Confirmed,
            t: 10.0,
            state: [100.0, 50.0, 0.0, 2.0, -1.0, 0.0],
            cov: vec![
                vec![4.0, 0.0, 0.0, 0.0],
                vec![0.0, 1.0, 0.0, 0.0],
                vec![0.0, 0.0, 4.0, 0.0],
                vec![0.0, 0.0, 0.0, 1.0],
            ],
            cov_dims: vec![0, 1, 3, 4],
            updated: true,
            age: 7,
            last_update: 10.0,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    #[test]
    fn the_ellipse_and_ellipsoid_are_the_95_percent_regions() {
        let e = Ellipse::of(&planar()).expect("an ellipse");
        assert!((e.semi_axes[0] - (4.0 * CHI2_95_2).sqrt()).abs() < 1e-12);
        assert!((e.semi_axes[1] - CHI2_95_2.sqrt()).abs() < 1e-12);
        assert!(Ellipsoid::of(&planar()).is_none());
        let mut k = planar();
        k.cov = vec![
            vec![1.0, 0.0, 0.0],
            vec![0.0, 9.0, 0.0],
            vec![0.0, 0.0, 4.0],
        ];
        k.cov_dims = vec![0, 1, 2];
        let e = Ellipsoid::of(&k).expect("an ellipsoid");
        let r = CHI2_95_3.sqrt();
        for (got, want) in e.semi_axes.iter().zip([3.0 * r, 2.0 * r, r]) {
            assert!((got - want).abs() < 1e-12, "{e:?}");
        }
        assert!((e.axes[0][1].abs() - 1.0).abs() < 1e-12, "{e:?}");
        // No (x, y) block, or a non-finite one: no ellipse.
        k.cov_dims = vec![3, 4, 5];
        assert!(Ellipse::of(&k).is_none());
        k.cov_dims = vec![0, 1, 2];
        k.cov[0][0] = f64::NAN;
        assert!(Ellipse::of(&k).is_none() && Ellipsoid::of(&k).is_none());
    }
}
