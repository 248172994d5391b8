//! Multi-target tracking in Stone Soup's roles, over any Gaussian filter.
//!
//! | role | here |
//! |---|---|
//! | filter of one track | [`TrackFilter`]: [`GaussianFilter`] (EKF, CDKF) or [`ImmFilter`] (IMM over them); the sensor model comes with each scan |
//! | measurement predictor | [`TrackFilter::predict_measurement`]: `ẑ`, `S` of a track under the scan's sensor |
//! | hypothesiser | [`hypothesise`]: NIS of every detection |
//! | gater | [`Gater`]: `d² ≤ χ²_M⁻¹(P_G)` ([`chi2_quantile`](crate::metrics::chi2_quantile)) |
//! | data associator | [`global_nearest_neighbour`]: optimal 2-D assignment of all tracks, confirmed and tentative, each with its own gate ([`assign::solve`], Jonker–Volgenant / Hungarian on `f64`) |
//! | initiator | [`SinglePointInitiator`] from any detection's position fix ([`Locate`](crate::measurement::Locate); angle-only with the ground-plane constraint) + [`MOfN`] confirmation |
//! | deleter | [`Deleter`]: consecutive misses or position-covariance growth |
//! | tracker | [`Tracker::step`]: predict, associate, update or coast, confirm / delete, initiate; returns [`TrackEvent`]s |
//! | tracker of cooperative targets | [`identified::IdentifiedTracks`]: reports that carry their identity (ADS-B, AIS), one Kalman filter per identity, no association |
//!
//! [`metrics`] has GOSPA and track-continuity counts, [`format`](mod@format) reads the multi-target extension
//! of `gcs-scenario/1` (`FORMAT-MULTI.md`), and [`generate`] writes seeded crossing-target
//! scenarios with clutter.
//!
//! ```
//! use harrier_core::filter::Extended;
//! use harrier_core::measurement::{AzEl, Geometry, Position};
//! use harrier_core::motion::ConstantVelocity;
//! use harrier_core::tracker::{
//!     Association, Deleter, Gater, GaussianFilter, MOfN, SinglePointInitiator, TrackEvent, Tracker,
//!     TrackerConfig,
//! };
//! use nalgebra::{Vector2, Vector3};
//!
//! let filter = GaussianFilter { filter: Extended, motion: ConstantVelocity::<4>::new(0.5) };
//! let config = TrackerConfig {
//!     gater: Gater::chi2(0.999, 2).unwrap(),
//!     tentative_gater: Gater::chi2(0.99, 2).unwrap(),
//!     confirm: MOfN::new(2, 3).unwrap(),
//!     deleter: Deleter::new(3, 1e4, 2).unwrap(),
//!     association: Association::Gnn,
//! };
//! let init = SinglePointInitiator::new(10.0, 10.0).unwrap();
//! let mut tracker = Tracker::new(filter, init, config);
//! let ground = Geometry::planar(0.0);
//! let fixes = Position::new(ground, [5.0, 5.0]);
//! for k in 0..3 {
//!     let t = f64::from(k);
//!     let events = tracker
//!         .step(t, &fixes, &[Vector2::new(10.0 * t, 0.0), Vector2::new(-300.0 * t, 900.0)])
//!         .unwrap();
//!     assert!(events.iter().any(|e| matches!(e, TrackEvent::Born { .. } | TrackEvent::Updated { .. })));
//! }
//! assert_eq!(tracker.confirmed().len(), 1); // the clutter never confirms
//! // A camera 100 m up sees the target: the same track is updated through az/el.
//! let camera = AzEl::new(ground, Vector3::new(0.0, -100.0, 100.0), [0.01, 0.01]);
//! let d = Vector3::<f64>::new(30.0, 100.0, -100.0);
//! let z = Vector2::new(d.x.atan2(d.y), d.z.atan2(d.x.hypot(d.y)));
//! let events = tracker.step(3.0, &camera, &[z]).unwrap();
//! assert!(events.iter().any(|e| matches!(e, TrackEvent::Updated { id: 1, .. })));
//! ```

pub mod assign;
mod associate;
mod delete;
pub mod ehm;
pub mod existence;
mod filter;
pub mod format;
mod gate;
pub mod generate;
pub mod identified;
mod initiate;
pub mod jipda;
pub mod jpda_star;
pub mod metrics;
pub mod mht;
mod multi;
pub mod retrodict;
mod track;

pub use associate::{
    Cluster, Gater, Hypothesis, TrackHypotheses, clusters, global_nearest_neighbour, hypothesise,
    hypothesise_scan,
};
pub use delete::{DeleteReason, Deleter};
pub use existence::Existence;
pub use filter::{CimmFilter, GaussianFilter, ImmFilter, TrackFilter};
pub use gate::DetectionIndex;
pub use initiate::{Initiator, MOfN, SinglePointInitiator, Verdict};
pub use mht::Mht;
pub use multi::{
    Association, AssociationStats, DetectionModel, Jipda, Track, TrackEvent, TrackSnapshot,
    TrackStatus, Tracker, TrackerConfig,
};
