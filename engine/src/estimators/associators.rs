//! The associators of the multi-target tracker by name ([`AssociatorInfo`]s, listed by
//! [`crate::registry::ASSOCIATORS`]): `gnn` (global nearest neighbour, M-of-N), `jipda` (joint
//! integrated probabilistic data association with track existence) and `mht` (the multi-scan,
//! track-oriented MHT), each built from a [`Deployment`] (its `detection` block gives `P_D`) and
//! `--param` settings into harrier-core's [`Association`]. Any of them runs with any track filter
//! ([`multi_target`](super::multi_target)).

use harrier_core::tracker::existence::Existence;
use harrier_core::tracker::{Association, DetectionModel, Jipda, Mht};

use super::count;
use crate::{AssociatorInfo, Deployment, EngineError, Params, setup};

/// The soft and multi-scan associators' sensor and existence parameters.
const EXISTENCE_PARAMS: [(&str, &str); 7] = [
    (
        "pd",
        "detection probability per scan (default detection.pd of the scenario, else 0.9)",
    ),
    (
        "clutter_density",
        "clutter per unit of measurement space, per m² for planar position sensors (default \
         detection.clutter_rate / region area for those, else estimated from each scan)",
    ),
    (
        "survival",
        "probability that a target persists one second (default 0.995)",
    ),
    (
        "existence_initial",
        "existence of a track started from one detection (default 5 / (5 + detection.clutter_rate) \
         within [0.02, 0.5]: 1/3 at 10 clutter detections a scan, 0.09 at 50; 0.1 without a \
         clutter rate)",
    ),
    (
        "existence_confirm",
        "existence that confirms a track (default 0.9)",
    ),
    (
        "existence_delete",
        "existence below which a track is deleted (default 0.01)",
    ),
    (
        "birth",
        "a detection that is no track's with at least this probability starts one (default 0.5)",
    ),
];

/// `jipda`'s parameters.
const JIPDA_PARAMS: &[(&str, &str)] = &[
    EXISTENCE_PARAMS[0],
    EXISTENCE_PARAMS[1],
    EXISTENCE_PARAMS[2],
    EXISTENCE_PARAMS[3],
    EXISTENCE_PARAMS[4],
    EXISTENCE_PARAMS[5],
    EXISTENCE_PARAMS[6],
    (
        "max_net_nodes",
        "nodes per layer of a cluster's EHM net before it is cut, counted (default 10000)",
    ),
    (
        "star_nodes",
        "coalescence avoidance (JPDA*): nodes a cluster's enumeration of joint events may visit; \
         a larger cluster gets the exact JIPDA marginals, counted (default 20000; 0: plain JIPDA)",
    ),
    (
        "star_gate",
        "JPDA* prunes the permutations of tracks that move together: velocities within this \
         probability's chi-square ellipsoid (default 0.9; 1: every track)",
    ),
];

/// `gnn`: global nearest neighbour.
pub const ASSOCIATOR_GNN: AssociatorInfo = AssociatorInfo {
    name: "gnn",
    summary: "global nearest neighbour: one optimal assignment per cluster and scan, M-of-N \
              confirmation, deletion after misses",
    params: &[],
    build: |_, _| Ok(Association::Gnn),
};

/// `jipda`: joint integrated probabilistic data association.
pub const ASSOCIATOR_JIPDA: AssociatorInfo = AssociatorInfo {
    name: "jipda",
    summary: "joint integrated PDA: exact marginals (EHM) per cluster, mixture update, track \
              existence confirms and deletes",
    params: JIPDA_PARAMS,
    build: |d, p| {
        Ok(Association::Jipda(Jipda {
            detection: detection_model(d, p)?,
            existence: existence(d, p)?,
            birth: unit(p, "birth", 0.5)?,
            max_net_nodes: count(p, "max_net_nodes", 10_000)? as usize,
            star_nodes: star_nodes(p)?,
            star_gate: unit(p, "star_gate", 0.9)?,
        }))
    },
};

/// `mht`'s parameters.
const MHT_PARAMS: &[(&str, &str)] = &[
    EXISTENCE_PARAMS[0],
    EXISTENCE_PARAMS[1],
    EXISTENCE_PARAMS[2],
    EXISTENCE_PARAMS[3],
    EXISTENCE_PARAMS[4],
    EXISTENCE_PARAMS[5],
    (
        "window",
        "scans of the sliding window; a scan's association is final window − 1 scans later \
         (default 3)",
    ),
    ("max_leaves", "hypotheses per track (default 16)"),
    (
        "max_hypotheses",
        "hypotheses of all tracks together (default 100000)",
    ),
    (
        "max_search",
        "nodes a cluster's global-hypothesis search visits before it keeps its best so far, \
         counted (default 100000)",
    ),
    (
        "hysteresis",
        "log-likelihood ratio by which another hypothesis must beat the reported one to replace \
         it (default 0)",
    ),
    (
        "mixture",
        "1: a track reports its hypotheses' mixture, each weighed by the best global hypothesis \
         that holds it; 0: the best global hypothesis' (default 1)",
    ),
];

/// `mht`: the multi-scan associator.
pub const ASSOCIATOR_MHT: AssociatorInfo = AssociatorInfo {
    name: "mht",
    summary: "multi-scan: track-oriented MHT over a sliding window (N-scan pruning), each \
              track's hypotheses reported as their mixture by max-marginals, track existence \
              confirms and deletes",
    params: MHT_PARAMS,
    build: |d, p| {
        let mut m = Mht::new(
            detection_model(d, p)?,
            existence(d, p)?,
            count(p, "window", 3)? as usize,
            count(p, "max_leaves", 16)? as usize,
            count(p, "max_hypotheses", 100_000)? as usize,
            count(p, "max_search", 100_000)? as usize,
            p.get("hysteresis", 0.0),
        )?;
        m.mixture = p.get("mixture", 1.0) != 0.0;
        Ok(Association::Mht(m))
    },
};

/// `P_D` and the clutter density of `--param pd`, `--param clutter_density`, or the
/// deployment's `detection` (the density itself is set per scan by the engine).
fn detection_model(d: &Deployment, p: &Params) -> Result<DetectionModel, EngineError> {
    let pd = p.get("pd", d.detection.as_ref().map_or(0.9, |x| x.pd).min(0.999));
    Ok(DetectionModel::new(pd, p.opt("clutter_density"))?)
}

/// Births a scan that the default initial existence weighs against the deployment's clutter
/// detections a scan (`ψ₀ = b / (b + clutter_rate)`): a tuning of how fast tracks confirm
/// against how many false ones do, not a measured birth rate. At 10 clutter detections a scan
/// ψ₀ = 1/3 confirms a target seen, missed and seen again on the third scan (the 2-of-3 rule's
/// timing); at 50 a scan ψ₀ = 0.09 keeps the false tracks down.
const BIRTHS_PER_SCAN: f64 = 5.0;

/// The initial existence when the parameters give none: [`BIRTHS_PER_SCAN`] against the
/// deployment's `detection.clutter_rate`, within [0.02, 0.5]; 0.1 without a clutter rate.
fn default_initial_existence(d: &Deployment) -> f64 {
    d.detection
        .as_ref()
        .filter(|x| x.clutter_rate > 0.0 && x.clutter_rate.is_finite())
        .map_or(0.1, |x| {
            (BIRTHS_PER_SCAN / (BIRTHS_PER_SCAN + x.clutter_rate)).clamp(0.02, 0.5)
        })
}

/// The existence chain and thresholds of the parameters.
fn existence(d: &Deployment, p: &Params) -> Result<Existence, EngineError> {
    Ok(Existence::new(
        p.get("survival", 0.995),
        p.get("existence_initial", default_initial_existence(d)),
        p.get("existence_confirm", 0.9),
        p.get("existence_delete", 0.01),
    )?)
}

/// `--param star_nodes`: a whole number in [0, 10⁷] (0 turns JPDA*'s pruning off).
fn star_nodes(p: &Params) -> Result<usize, EngineError> {
    let v = p.get("star_nodes", 20_000.0);
    if v.fract() != 0.0 || !(0.0..=1e7).contains(&v) {
        return Err(setup(
            "--param star_nodes must be a whole number in [0, 10000000]",
        ));
    }
    Ok(v as usize)
}

/// A probability parameter in [0, 1].
fn unit(p: &Params, name: &str, default: f64) -> Result<f64, EngineError> {
    let v = p.get(name, default);
    if !(0.0..=1.0).contains(&v) {
        return Err(setup(format!("--param {name} must be in [0, 1]")));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_core::scenario::DetectionSpec;

    fn deployment(clutter_rate: Option<f64>) -> Deployment {
        Deployment {
            detection: clutter_rate.map(|clutter_rate| DetectionSpec {
                pd: 0.9,
                clutter_rate,
                region: None,
            }),
            ..Deployment::planar(1)
        }
    }

    /// The initial existence falls as the clutter rate rises, within [0.02, 0.5], and the
    /// parameter overrides it.
    #[test]
    fn the_initial_existence_is_weighed_against_the_clutter_rate() {
        let initial = |rate: Option<f64>, p: &Params| {
            existence(&deployment(rate), p).expect("existence").initial
        };
        let none = Params::default();
        assert!((initial(Some(10.0), &none) - 1.0 / 3.0).abs() < 1e-12);
        assert!((initial(Some(50.0), &none) - 5.0 / 55.0).abs() < 1e-12);
        assert_eq!(initial(Some(1.0), &none), 0.5);
        assert_eq!(initial(Some(1e6), &none), 0.02);
        assert_eq!(initial(Some(0.0), &none), 0.1);
        assert_eq!(initial(None, &none), 0.1);
        let p = Params::parse(&["existence_initial=0.2"]).expect("parameters");
        assert_eq!(initial(Some(10.0), &p), 0.2);
    }
}
