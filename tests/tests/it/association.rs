//! Acceptance of the associators on close groups of turning ground targets (harrier-core's
//! `generate::groups`, the data of BENCHMARKS.md "Association under ambiguity"): a short version
//! of `harrier track-eval` over three seeds of each shape, each tracker as `harrier replay -e
//! tracker --track-filter F --associator A` runs it with its defaults, scored with GOSPA
//! (c = 20 m, p = 2) and the continuity counts.
//!
//! What holds on every shape: `jipda` and `mht` (IMM tracks) at least 5 % lower GOSPA than `gnn`
//! with the same filter and than today's default (`gnn`, `ekf`), no more false tracks, every target
//! confirmed. On crossings, JIPDA swaps at most half of GNN's identities. Where they lose (JIPDA's
//! coalescence on close parallel targets; the multi-scan associator's swaps, close to GNN's; the
//! later confirmation of existence-based rules) is printed and set out in BENCHMARKS.md with the
//! ten-seed figures, not asserted.

use harrier_core::scenario::ScenarioData;
use harrier_core::tracker::format::MultiScenario;
use harrier_core::tracker::generate::groups;
use harrier_engine::Params;
use harrier_tools::gen_multi::shape_config;
use harrier_tools::replay::{TrackerChoice, run_tracker};
use harrier_tools::track_eval::{MultiScore, score};

/// Summed figures of one tracker over the seeds.
#[derive(Debug, Default)]
struct Sum {
    gospa: f64,
    swaps: usize,
    false_tracks: usize,
    never: usize,
    worst: usize,
}

fn run(shape: &str, seeds: std::ops::RangeInclusive<u64>, filter: &str, associator: &str) -> Sum {
    let cfg = shape_config(shape).unwrap();
    let mut sum = Sum::default();
    for seed in seeds {
        let g = groups::generate(seed, &cfg).unwrap();
        let m = MultiScenario::parse(&g.scenario_json, &g.measurements_jsonl, Some(&g.truth_csv))
            .unwrap();
        let data = ScenarioData::parse(&g.scenario_json, &g.measurements_jsonl, None).unwrap();
        let choice = TrackerChoice {
            filter: filter.into(),
            associator: associator.into(),
        };
        let report = run_tracker(&data, &choice, &Params::default()).unwrap();
        let s: MultiScore = score(&m, &report.estimates, 20.0).unwrap();
        sum.gospa += s.gospa;
        sum.swaps += s.swaps;
        sum.false_tracks += s.false_tracks;
        match s.worst_delay {
            Some(d) => sum.worst = sum.worst.max(d),
            None => sum.never += 1,
        }
        if associator != "gnn" {
            let a = report.association.unwrap();
            assert!(a.clusters > 0, "{associator}: no cluster solved");
        }
    }
    sum
}

#[test]
fn soft_and_multi_scan_association_beat_gnn_on_close_groups() {
    for shape in ["crossing", "parallel", "opposing", "dense"] {
        let seeds = 1..=3;
        let default = run(shape, seeds.clone(), "ekf", "gnn");
        let gnn = run(shape, seeds.clone(), "imm", "gnn");
        let jipda = run(shape, seeds.clone(), "imm", "jipda");
        let mht = run(shape, seeds.clone(), "imm", "mht");
        println!(
            "{shape}: mean GOSPA gnn/ekf {:.2}, gnn/imm {:.2}, jipda {:.2}, mht {:.2} m; swaps \
             {}, {}, {}, {}; false tracks {}, {}, {}, {}; worst confirmation delay {}, {}, {}, {}",
            default.gospa / 3.0,
            gnn.gospa / 3.0,
            jipda.gospa / 3.0,
            mht.gospa / 3.0,
            default.swaps,
            gnn.swaps,
            jipda.swaps,
            mht.swaps,
            default.false_tracks,
            gnn.false_tracks,
            jipda.false_tracks,
            mht.false_tracks,
            default.worst,
            gnn.worst,
            jipda.worst,
            mht.worst,
        );
        for (name, s) in [("jipda", &jipda), ("mht", &mht)] {
            assert!(
                s.gospa <= 0.95 * gnn.gospa,
                "{shape}: {name} {s:?} vs gnn {gnn:?}"
            );
            assert!(s.gospa <= 0.95 * default.gospa, "{shape}: {name} {s:?}");
            assert!(s.false_tracks <= gnn.false_tracks, "{shape}: {name} {s:?}");
            assert_eq!(s.never, 0, "{shape}: {name}: a target never confirmed");
            assert!(s.worst <= 10, "{shape}: {name}: worst delay {}", s.worst);
        }
        if shape == "crossing" {
            assert!(2 * jipda.swaps <= gnn.swaps, "{jipda:?} vs {gnn:?}");
        }
    }
}
