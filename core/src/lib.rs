//! # harrier-core
//!
//! The pure heart of Harrier: state estimators, motion and measurement models, metrics and the
//! `gcs-scenario/1` file format. It does no I/O, no async, reads no clock and uses no global RNG:
//! every function is deterministic given its inputs, and numeric failures come back as
//! [`EstimationError`], never as panics.
//!
//! ## Design
//!
//! The cut follows Stone Soup's roles, with nalgebra const-generic sizes:
//!
//! * models describe the world and hold no state: [`motion::TransitionModel`] (`x_k = f(x_{k-1}, Δt) + w`)
//!   and [`measurement::MeasurementModel`] (`z = h(x) + v`);
//! * filters say *how* to propagate a state through a model: [`filter::Predictor`] and
//!   [`filter::Updater`]. An update returns a [`state::Posterior`] that keeps the innovation and its
//!   covariance, which gating, NIS and IMM likelihoods need.
//!
//! Everything is monomorphised; the server erases filter types behind one registry (its drivers
//! box them, its registry builds them by name).
//!
//! ```
//! use harrier_core::filter::{Extended, Predictor, Updater};
//! use harrier_core::measurement::{Geometry, RangeBearing};
//! use harrier_core::motion::ConstantVelocity;
//! use harrier_core::state::Gaussian;
//! use nalgebra::{Matrix4, Vector2, Vector3, Vector4};
//!
//! let cv = ConstantVelocity::<4>::new(1.0); // planar [x, y, vx, vy], accel spectral density 1 m²/s³
//! let prior = Gaussian::new(Vector4::new(1000.0, 5000.0, 15.0, -10.0),
//!                           Matrix4::from_diagonal(&Vector4::new(1e4, 1e4, 25.0, 25.0))).unwrap();
//! let predicted = Extended.predict(&cv, &prior, 1.0).unwrap();
//! let radar = RangeBearing::new(Geometry::planar(0.0), Vector3::zeros(), [5.0, 0.005]);
//! let post = Extended.update(&radar, &predicted, &Vector2::new(5090.0, 0.2)).unwrap();
//! assert!(post.nis().unwrap() >= 0.0);
//! ```
#![deny(missing_docs)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

pub mod detection;
pub mod error;
pub mod filter;
pub mod fusion;
pub mod guidance;
pub mod linalg;
pub mod measurement;
pub mod metrics;
pub mod motion;
pub mod registration;
pub mod road;
pub mod scenario;
pub mod state;
pub mod tracker;

pub use error::EstimationError;

/// `Result` with [`EstimationError`] as the error type.
pub type Result<T, E = EstimationError> = std::result::Result<T, E>;
