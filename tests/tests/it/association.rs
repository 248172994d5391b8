//! Acceptance of the associators on close groups of turning ground targets (harrier-core's
//! `generate::groups`, the data of BENCHMARKS.md "Association under ambiguity"): a short version
//! of `harrier track-eval` over three seeds of each shape, each tracker as `harrier replay -e
//! tracker --track-filter F --associator A` runs it with its defaults, scored with GOSPA
//! (c = 20 m, p = 2) and the continuity counts.
//!
//! What holds on every shape: `jipda` and `mht` (IMM tracks) at least 5 % lower GOSPA than `gnn`
//! with the same filter and than today's default (`gnn`, `ekf`), no more false tracks, every target
//! confirmed, and outside dense clutter at most one target fewer within their first three scans
//! than GNN (98–99 % of GNN's count over fifty seeds). On crossings, plain JIPDA
//! (`star_nodes=0`) swaps at most half of GNN's identities; on close parallel targets, the
//! default JIPDA with JPDA*'s coalescence avoidance at most half of plain JIPDA's. Where they lose (JPDA*'s hard guesses at crossings of
//! tracks that move together; the multi-scan associator's swaps, three quarters of GNN's; the later
//! confirmation of existence-based rules in dense clutter) is printed and set out in
//! BENCHMARKS.md with the ten- and fifty-seed figures, not asserted.

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
    /// Targets confirmed within their first three scans.
    within_3: usize,
}

fn run(
    shape: &str,
    seeds: std::ops::RangeInclusive<u64>,
    filter: &str,
    associator: &str,
    params: &Params,
) -> Sum {
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
            register: false,
        };
        let report = run_tracker(&data, &choice, params).unwrap();
        let s: MultiScore = score(&m, &report.estimates, 20.0).unwrap();
        sum.gospa += s.gospa;
        sum.swaps += s.swaps;
        sum.false_tracks += s.false_tracks;
        sum.within_3 += s.within_3;
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
        let defaults = Params::default();
        let default = run(shape, seeds.clone(), "ekf", "gnn", &defaults);
        let gnn = run(shape, seeds.clone(), "imm", "gnn", &defaults);
        let jipda = run(shape, seeds.clone(), "imm", "jipda", &defaults);
        let plain = Params::default().with("star_nodes", 0.0);
        let plain = run(shape, seeds.clone(), "imm", "jipda", &plain);
        let mht = run(shape, seeds.clone(), "imm", "mht", &defaults);
        println!(
            "{shape}: mean GOSPA gnn/ekf {:.2}, gnn/imm {:.2}, jipda {:.2} (plain {:.2}), mht \
             {:.2} m; swaps {}, {}, {} ({}), {}; false tracks {}, {}, {}, {}; worst \
             confirmation delay {}, {}, {}, {}; confirmed within 3 scans {}, {}, {}, {}",
            default.gospa / 3.0,
            gnn.gospa / 3.0,
            jipda.gospa / 3.0,
            plain.gospa / 3.0,
            mht.gospa / 3.0,
            default.swaps,
            gnn.swaps,
            jipda.swaps,
            plain.swaps,
            mht.swaps,
            default.false_tracks,
            gnn.false_tracks,
            jipda.false_tracks,
            mht.false_tracks,
            default.worst,
            gnn.worst,
            jipda.worst,
            mht.worst,
            default.within_3,
            gnn.within_3,
            jipda.within_3,
            mht.within_3,
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
            // Outside dense clutter the initial existence weighed against the clutter rate
            // confirms nearly as many targets within 3 scans as GNN's 2 of 3: at most one fewer
            // of the 22–33 targets of three seeds (one is 3–5 % of them; over fifty seeds
            // 98–99 % of GNN's count).
            if shape != "dense" {
                assert!(
                    s.within_3 + 1 >= gnn.within_3,
                    "{shape}: {name} {s:?} vs {gnn:?}"
                );
            }
        }
        match shape {
            // Plain JIPDA keeps each track's momentum through a crossing.
            "crossing" => assert!(2 * plain.swaps <= gnn.swaps, "{plain:?} vs {gnn:?}"),
            // JPDA* (the default) keeps close parallel tracks from coalescing.
            "parallel" => assert!(2 * jipda.swaps <= plain.swaps, "{jipda:?} vs {plain:?}"),
            _ => {}
        }
    }
}
