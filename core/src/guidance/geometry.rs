//! Plane geometry the guidance laws share (angles, rotations, clamping without panics).

use nalgebra::Vector2;

/// `max(lo, min(hi, x))` without `f64::clamp`'s panic on `lo > hi` or NaN bounds (limits and
/// gains come from callers).
#[inline]
pub(crate) fn clampf(x: f64, lo: f64, hi: f64) -> f64 {
    x.min(hi).max(lo)
}

/// `v` rotated by +90° (counter-clockwise).
#[inline]
pub(crate) fn perp(v: Vector2<f64>) -> Vector2<f64> {
    Vector2::new(-v.y, v.x)
}

/// `v` rotated by `a` radians counter-clockwise.
#[inline]
pub(crate) fn rotate(v: Vector2<f64>, a: f64) -> Vector2<f64> {
    let (s, c) = a.sin_cos();
    Vector2::new(c * v.x - s * v.y, s * v.x + c * v.y)
}

/// Signed angle from `a` to `b` in `[-π, π]`.
#[inline]
pub(crate) fn angle_between(a: Vector2<f64>, b: Vector2<f64>) -> f64 {
    (a.x * b.y - a.y * b.x).atan2(a.dot(&b))
}
