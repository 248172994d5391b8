//! # harrier-engine
//!
//! The estimation engine: what an estimator looks like once its filter types are erased, in its
//! two shapes, the drivers that build them from harrier-core's filters, and the registry that
//! names them. No I/O: the live service (harrier-server) and the offline tools (harrier-tools)
//! both run estimators through it.
//!
//! - [`replay`]: every estimator Harrier can run by name over a scenario implements
//!   [`ReplayEstimator`] and is described by an [`EstimatorInfo`]. A `Box<dyn ReplayEstimator>` is
//!   the only form in which the offline tools (`replay`, `guidance-sim`) see a filter.
//! - [`track`]: the live service's multi-target tracker, [`TrackEngine`], described by a
//!   [`TrackFilterInfo`].
//!
//! The drivers in [`estimators`] build both from a scenario and [`Params`], and [`registry`]
//! lists them and builds one by name: the one place where a name becomes a
//! `Box<dyn ReplayEstimator>` ([`registry::build`]) or a `Box<dyn TrackEngine>`
//! ([`registry::build_track_filter`]). The crate root re-exports what [`replay`] and [`track`]
//! define, so users name `harrier_engine::…`.
//!
//! [`replay`] and [`track`] are leaves: drivers depend on them and never on the registry.

mod error;
pub mod estimators;
pub mod region;
pub mod registry;
pub mod replay;
pub mod track;

pub use error::{EngineError, setup};
pub use region::{CHI2_95_2, CHI2_95_3, Ellipse, Ellipsoid};
pub use replay::{BuildFn, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step};
pub use track::{
    AssociatorBuildFn, AssociatorInfo, BiasTermView, Deployment, Handover, RegisteredSensor,
    ScanOutcome, ScanSource, SensorBiasView, SensorScan, TrackEngine, TrackFilterBuildFn,
    TrackFilterInfo, TrackStatus, TrackView,
};
