//! # harrier-tools
//!
//! The offline tools of the `harrier` command, apart from the live service: each reads files,
//! runs estimators from [`harrier_engine::registry`] and writes files.
//!
//! * [`replay`] (`harrier replay`): a named estimator over a `gcs-scenario/1` directory, scored
//!   against its truth.
//! * [`guidance_sim`] (`harrier guidance-sim`): closed-loop guidance scenarios and their figures.
//! * [`gen_multi`] (`harrier gen-multi`): a seeded multi-target scenario (crossing targets, or
//!   close groups of turning ones).
//! * [`gen_registration`] (`harrier gen-registration`): a seeded sensor-registration scenario.
//! * [`track_eval`] (`harrier track-eval`): the multi-target tracker's associators compared on
//!   generated close groups, or an estimates file scored.
//! * [`sessions`] (`harrier sessions`): a recording's sessions listed, summarised and exported
//!   ([`harrier_recording`]).

pub mod gen_multi;
pub mod gen_registration;
pub mod guidance_sim;
pub mod replay;
pub mod sessions;
pub mod track_eval;
