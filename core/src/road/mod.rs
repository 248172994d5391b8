//! Road networks (FORMAT.md §2 `roads`) and the road constraint of \[CIMM\] §3.1 as a
//! pseudo-measurement.
//!
//! A road is a centre line of [`RoadSegment`]s (lines and circular arcs) in travel order.
//! [`Road::project`] finds the nearest point of the centre line: the foot point, the unit tangent
//! (travel direction), the signed lateral offset (> 0 left of the travel direction) and its
//! gradient. Because consecutive segments share their end points, the foot point and the offset
//! are continuous across segment joins; at a kink the foot stays at the corner and the offset
//! gradient turns with `p − corner`. Beyond the free ends of a road the end segment is extended
//! along its tangent, so the constraint stays defined (and smooth) before the first and after the
//! last segment.
//!
//! [`RoadConstraint`] is the pseudo-measurement of \[CIMM\] §3.1 (Tahk & Speyer's "constraint as
//! an additional fictitious measurement"): `z^r = 0 = h_r(x) + v^r`. The paper writes the constraint
//! per segment (a line `y = tan θ·x + b` or an arc `(x − x_c)² + (y − y_c)² = R²`) with noise
//! variance `σ_road²`; here `h_r` is the signed distance to the centre line (which is that
//! constraint normalised to metres, on whichever segment is nearest) with std `sigma_m`, stacked
//! with the velocity component normal to the road (velocity along the tangent) with std
//! `sigma_v`. Both are nonlinear in the state; the EKF linearises them at each mode's predicted
//! mean (the CEKF of \[CIMM\] §3.1).
//!
//! Split by concern: the road, its projection and the network in `network.rs`, the segments'
//! geometry in `segment.rs`, the pseudo-measurement in `constraint.rs` and
//! [`road_from_turn_legs`] in `turn_legs.rs`.
//!
//! # References
//! * \[CIMM\] `shared/papers/003`, §3.1.
//! * M. Tahk, J. L. Speyer, "Target tracking problems subject to kinematic constraints", IEEE TAC
//!   35(3), 1990.

mod constraint;
mod network;
mod segment;
#[cfg(test)]
mod tests;
mod turn_legs;

pub use constraint::RoadConstraint;
pub use network::{GEOMETRY_TOL_M, MAX_ROAD_COORD_M, Road, RoadNetwork, RoadPoint};
pub use segment::RoadSegment;
pub use turn_legs::road_from_turn_legs;
