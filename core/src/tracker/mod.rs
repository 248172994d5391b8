//! Multi-target tracking in Stone Soup's roles, over any Gaussian filter.
//!
//! | role | here |
//! |---|---|
//! | filter of one track | [`TrackFilter`]: [`GaussianFilter`] wraps any `Predictor` + `Updater` on [`Gaussian`](crate::state::Gaussian) states; an IMM implements it on its own state |
//! | hypothesiser | [`hypothesise`]: predicted measurement, NIS of every detection |
//! | gater | [`Gater`]: `d² ≤ χ²_M⁻¹(P_G)` ([`chi2_quantile`](crate::metrics::chi2_quantile)) |
//! | data associator | [`global_nearest_neighbour`]: optimal 2-D assignment ([`assign::solve`], Jonker–Volgenant / Hungarian on `f64`) |
//! | initiator | [`SinglePointInitiator`] (velocity prior) + [`MOfN`] confirmation |
//! | deleter | [`Deleter`]: consecutive misses or position-covariance growth |
//! | tracker | [`Tracker::step`]: predict, associate (confirmed tracks first), update or coast, confirm / delete, initiate |
//!
//! [`metrics`] has GOSPA and track-continuity counts, [`scenario`] reads the multi-target extension
//! of `gcs-scenario/1` (`FORMAT-MULTI.md`), and [`generate`] writes seeded crossing-target
//! scenarios with clutter.
//!
//! ```
//! use harrier_core::filter::Kalman;
//! use harrier_core::measurement::{Geometry, Position};
//! use harrier_core::motion::ConstantVelocity;
//! use harrier_core::tracker::{
//!     Deleter, Gater, GaussianFilter, MOfN, SinglePointInitiator, Tracker, TrackerConfig,
//! };
//! use nalgebra::{Matrix2, Vector2};
//!
//! let filter = GaussianFilter {
//!     filter: Kalman,
//!     motion: ConstantVelocity::<4>::new(0.5),
//!     sensor: Position::new(Geometry::planar(0.0), [5.0, 5.0]),
//! };
//! let config = TrackerConfig {
//!     gater: Gater::chi2(0.999, 2).unwrap(),
//!     tentative_gater: Gater::chi2(0.99, 2).unwrap(),
//!     confirm: MOfN::new(2, 3).unwrap(),
//!     deleter: Deleter::new(3, 1e4, 2).unwrap(),
//! };
//! let init = SinglePointInitiator::new(Matrix2::identity() * 25.0, 10.0).unwrap();
//! let mut tracker = Tracker::new(filter, init, config);
//! for k in 0..3 {
//!     let t = f64::from(k);
//!     tracker.step(t, &[Vector2::new(10.0 * t, 0.0), Vector2::new(-300.0 * t, 900.0)]).unwrap();
//! }
//! assert_eq!(tracker.confirmed().len(), 1); // the clutter never confirms
//! ```

pub mod assign;
mod associate;
mod delete;
mod filter;
pub mod generate;
mod initiate;
pub mod metrics;
mod multi;
pub mod scenario;

pub use associate::{Gater, Hypothesis, TrackHypotheses, global_nearest_neighbour, hypothesise};
pub use delete::Deleter;
pub use filter::{GaussianFilter, MeasurementPrediction, TrackFilter};
pub use initiate::{Initiator, MOfN, SinglePointInitiator, Verdict};
pub use multi::{Track, TrackSnapshot, TrackStatus, Tracker, TrackerConfig};
