//! Tests of the tracker's life cycle, adoption and input checks (GNN), and of the soft and
//! multi-scan associators.

use super::*;
use crate::filter::Extended;
use crate::measurement::{Geometry, Position};
use crate::motion::ConstantVelocity;
use crate::tracker::filter::GaussianFilter;
use crate::tracker::initiate::SinglePointInitiator;
use nalgebra::Vector2;

type Kf = GaussianFilter<Extended, ConstantVelocity<4>>;
fn cam() -> Position<2> {
    Position::new(Geometry::planar(0.0), [5.0, 5.0])
}

fn tracker(m: u32, n: u32) -> Tracker<Kf, SinglePointInitiator, 4> {
    let filter = GaussianFilter {
        filter: Extended,
        motion: ConstantVelocity::new(0.5),
    };
    let init = SinglePointInitiator::new(10.0, 10.0).unwrap();
    let config = TrackerConfig {
        gater: Gater::chi2(0.999, 2).unwrap(),
        tentative_gater: Gater::chi2(0.99, 2).unwrap(),
        confirm: MOfN::new(m, n).unwrap(),
        deleter: Deleter::new(3, 1e4, 2).unwrap(),
        association: Association::Gnn,
    };
    Tracker::new(filter, init, config)
}

#[test]
fn adopted_tracks_keep_ids_and_records_and_go_on() {
    let mut a = tracker(2, 3);
    let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
    for k in 0..3 {
        a.step(f64::from(k), &cam(), &[at(f64::from(k))]).unwrap();
    }
    let taken: Vec<_> = a
        .records()
        .into_iter()
        .zip(a.snapshot())
        .map(|(r, s)| (r, s.estimate))
        .collect();
    assert_eq!(taken.len(), 1);
    let mut b = tracker(2, 3);
    b.adopt(2.0, &taken).unwrap();
    assert_eq!(b.records(), a.records());
    assert_eq!(b.next_id(), 2);
    let ev = b.step(3.0, &cam(), &[at(3.0), at(30.0)]).unwrap();
    assert!(ev.contains(&TrackEvent::Updated {
        id: 1,
        detection: 0,
        nis: match ev.iter().find_map(|e| match e {
            TrackEvent::Updated { nis, .. } => Some(*nis),
            _ => None,
        }) {
            Some(n) => n,
            None => panic!("no update in {ev:?}"),
        },
    }));
    assert!(
        ev.contains(&TrackEvent::Born {
            id: 2,
            detection: 1
        }),
        "{ev:?}"
    );
    let twice = vec![taken[0].clone(), taken[0].clone()];
    assert!(b.adopt(4.0, &twice).is_err());
    assert!(b.adopt(f64::NAN, &taken).is_err());
    assert_eq!(b.time(), Some(3.0));
}

#[test]
fn two_of_three_confirms_and_deletes() {
    let mut tr = tracker(2, 3);
    let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
    tr.step(0.0, &cam(), &[at(0.0)]).unwrap();
    assert_eq!(tr.tracks().len(), 1);
    assert!(tr.confirmed().is_empty());
    tr.step(1.0, &cam(), &[]).unwrap(); // miss: 1 of 2, still possible
    assert_eq!(tr.tracks().len(), 1);
    tr.step(2.0, &cam(), &[at(2.0)]).unwrap(); // 2 of 3: confirmed
    let c = tr.confirmed();
    assert_eq!((c.len(), c[0].id), (1, 1));
    for k in 3..6 {
        tr.step(f64::from(k), &cam(), &[at(f64::from(k))]).unwrap();
    }
    assert_eq!(tr.confirmed()[0].id, 1);
    assert!((tr.confirmed()[0].estimate.mean[2] - 10.0).abs() < 3.0);
    // Three misses delete it.
    for k in 6..9 {
        tr.step(f64::from(k), &cam(), &[]).unwrap();
    }
    assert!(tr.tracks().is_empty());
    // A lone clutter point: hit, miss, miss → dropped.
    tr.step(9.0, &cam(), &[Vector2::new(500.0, 500.0)]).unwrap();
    tr.step(10.0, &cam(), &[]).unwrap();
    tr.step(11.0, &cam(), &[]).unwrap();
    assert!(tr.tracks().is_empty());
    assert_eq!(tr.next_id, 3);
}

#[test]
fn rejects_bad_input_and_keeps_state() {
    let mut tr = tracker(2, 3);
    tr.step(1.0, &cam(), &[Vector2::new(0.0, 0.0)]).unwrap();
    let before = tr.tracks().to_vec();
    assert!(tr.step(0.5, &cam(), &[]).is_err());
    assert!(
        tr.step(2.0, &cam(), &[Vector2::new(f64::NAN, 0.0)])
            .is_err()
    );
    assert!(tr.step(f64::NAN, &cam(), &[]).is_err());
    assert_eq!(tr.tracks(), before.as_slice());
    assert_eq!(tr.time(), Some(1.0));
}

#[test]
fn events_tell_the_life_of_a_track() {
    let mut tr = tracker(2, 3);
    let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
    let ev = tr.step(0.0, &cam(), &[at(0.0)]).unwrap();
    assert_eq!(
        ev,
        vec![TrackEvent::Born {
            id: 1,
            detection: 0
        }]
    );
    let ev = tr.step(1.0, &cam(), &[at(1.0)]).unwrap();
    assert!(matches!(ev[0], TrackEvent::Updated { id: 1, detection: 0, nis } if nis >= 0.0));
    assert_eq!(ev[1], TrackEvent::Confirmed { id: 1 });
    let ev = tr.step(2.0, &cam(), &[]).unwrap();
    assert_eq!(ev, vec![TrackEvent::Coasted { id: 1, misses: 1 }]);
    tr.step(3.0, &cam(), &[]).unwrap();
    let ev = tr.step(4.0, &cam(), &[]).unwrap();
    assert_eq!(
        ev,
        vec![
            TrackEvent::Coasted { id: 1, misses: 3 },
            TrackEvent::Deleted {
                id: 1,
                reason: DeleteReason::Misses
            }
        ]
    );
    // A tentative track that cannot reach 2 of 3 is dropped as unconfirmed.
    tr.step(5.0, &cam(), &[at(0.0)]).unwrap();
    tr.step(6.0, &cam(), &[]).unwrap();
    let ev = tr.step(7.0, &cam(), &[]).unwrap();
    assert!(ev.contains(&TrackEvent::Deleted {
        id: 2,
        reason: DeleteReason::Unconfirmed
    }));
    // A camera looking up cannot start a track: rejected, with the reason.
    let sky = crate::measurement::AzEl::new(
        Geometry::planar(0.0),
        nalgebra::Vector3::new(0.0, 0.0, 10.0),
        [0.01, 0.01],
    );
    let ev = tr.step(8.0, &sky, &[Vector2::new(0.0, 0.5)]).unwrap();
    assert!(matches!(
        &ev[..],
        [TrackEvent::Rejected { id: None, detection: Some(0), reason }] if reason.contains("initiation")
    ));
}

#[test]
fn imm_tracks_through_any_sensor() {
    use crate::filter::{Imm, ModeModel};
    use crate::measurement::MeasKind;
    use crate::measurement::{RangeBearing, SensorModel};
    use crate::tracker::filter::ImmFilter;
    let q = 0.05;
    let imm = Imm::new(
        Extended,
        [ModeModel::Cv { q }, ModeModel::Ct { omega: 0.1, q }],
        [[0.95, 0.05], [0.05, 0.95]],
    )
    .unwrap();
    let filter = ImmFilter {
        imm,
        initial_probs: [0.9, 0.1],
    };
    let config = TrackerConfig {
        gater: Gater::chi2(0.999, 2).unwrap(),
        tentative_gater: Gater::chi2(0.99, 2).unwrap(),
        confirm: MOfN::new(2, 3).unwrap(),
        deleter: Deleter::new(3, 1e4, 2).unwrap(),
        association: Association::Gnn,
    };
    let mut tr = Tracker::new(
        filter,
        SinglePointInitiator::new(10.0, 10.0).unwrap(),
        config,
    );
    let radar = RangeBearing::new(
        Geometry::planar(0.0),
        nalgebra::Vector3::new(0.0, 0.0, 20.0),
        [2.0, 0.002],
    );
    let truth = |t: f64| nalgebra::Vector4::new(500.0 + 8.0 * t, 300.0, 8.0, 0.0);
    for k in 0..20 {
        let t = f64::from(k);
        let z = MeasurementModel::<4, 2>::function(&radar, &truth(t));
        // Every other scan comes through the run-time sensor model.
        if k % 2 == 0 {
            tr.step(t, &radar, &[z]).unwrap();
        } else {
            let any = SensorModel::new(
                MeasKind::RangeBearing,
                Geometry::planar(0.0),
                nalgebra::Vector3::new(0.0, 0.0, 20.0),
                &[2.0, 0.002],
                None,
            )
            .unwrap();
            tr.step_any(t, &any, &[z.as_slice()]).unwrap();
        }
    }
    let c = tr.confirmed();
    assert_eq!(c.len(), 1);
    assert!(
        (c[0].estimate.mean - truth(19.0)).norm() < 3.0,
        "{:?}",
        c[0].estimate.mean
    );
    assert_eq!(c[0].mode_probabilities.len(), 2);
    assert!(
        c[0].mode_probabilities[0] > 0.5,
        "{:?}",
        c[0].mode_probabilities
    );
    let pos = SensorModel::new(
        MeasKind::Position,
        Geometry::planar(0.0),
        nalgebra::Vector3::zeros(),
        &[1.0; 3],
        None,
    )
    .unwrap();
    assert!(tr.step_any(20.0, &pos, &[&[1.0, 2.0][..]]).is_err());
    assert_eq!(tr.time(), Some(19.0));
}

/// A JIPDA tracker: P_D 0.9, clutter 1e-6 per m², existence ψ₀ = 0.2, confirmed at 0.9,
/// deleted below 0.01.
fn jipda_tracker() -> Tracker<Kf, SinglePointInitiator, 4> {
    let mut t = tracker(2, 3);
    t.config.association = Association::Jipda(Jipda {
        detection: DetectionModel::new(0.9, Some(1e-6)).unwrap(),
        existence: Existence::new(0.99, 0.2, 0.9, 0.01).unwrap(),
        birth: 0.5,
        max_net_nodes: 1000,
        star_nodes: 20_000,
        star_gate: 1.0,
    });
    t
}

#[test]
fn jipda_confirms_and_deletes_by_existence() {
    let mut tr = jipda_tracker();
    let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
    let ev = tr.step(0.0, &cam(), &[at(0.0)]).unwrap();
    assert_eq!(
        ev,
        vec![TrackEvent::Born {
            id: 1,
            detection: 0
        }]
    );
    assert_eq!(tr.tracks()[0].existence, Some(0.2));
    // The second detection on the prediction: existence jumps (sparse clutter), confirmed.
    let ev = tr
        .step(1.0, &cam(), &[at(1.0) + Vector2::new(2.0, -1.0)])
        .unwrap();
    assert!(
        matches!(
            ev[0],
            TrackEvent::Updated {
                id: 1,
                detection: 0,
                ..
            }
        ),
        "{ev:?}"
    );
    assert!(ev.contains(&TrackEvent::Confirmed { id: 1 }), "{ev:?}");
    let psi = tr.snapshot()[0].existence.unwrap();
    assert!(psi > 0.9 && psi < 1.0, "{psi}");
    // A lone far detection starts a tentative track and changes nothing else.
    let ev = tr
        .step(2.0, &cam(), &[at(2.0), Vector2::new(900.0, 900.0)])
        .unwrap();
    assert!(
        ev.contains(&TrackEvent::Born {
            id: 2,
            detection: 1
        }),
        "{ev:?}"
    );
    // Misses lower the existence by the IPDA miss update until it falls below 0.01.
    let mut misses = 0;
    let mut last = tr.snapshot()[0].existence.unwrap();
    for k in 3..30 {
        let ev = tr.step(f64::from(k), &cam(), &[]).unwrap();
        misses += 1;
        if ev.contains(&TrackEvent::Deleted {
            id: 1,
            reason: DeleteReason::Misses,
        }) {
            break;
        }
        let psi = tr
            .tracks()
            .iter()
            .find(|k| k.id == 1)
            .unwrap()
            .existence
            .unwrap();
        let pdpg = 0.9 * 0.999;
        let want = (1.0 - pdpg) * 0.99 * last / (1.0 - pdpg * 0.99 * last);
        assert!((psi - want).abs() < 1e-9, "{psi} vs {want}");
        last = psi;
    }
    assert!((3..=8).contains(&misses), "deleted after {misses} misses");
    assert!(tr.tracks().iter().all(|k| k.id != 1));
}

#[test]
fn jipda_shares_a_detection_between_close_tracks_and_keeps_them_apart() {
    // Two targets 30 m apart on parallel lines, each detected every scan; JIPDA keeps one track on
    // each without swapping, and a scan with only one detection between them updates both a
    // little rather than pulling one onto the other.
    let mut tr = jipda_tracker();
    let a = |k: f64| Vector2::new(10.0 * k, 0.0);
    let b = |k: f64| Vector2::new(10.0 * k, 30.0);
    for k in 0..6 {
        let k = f64::from(k);
        tr.step(k, &cam(), &[a(k), b(k)]).unwrap();
    }
    let ids: Vec<u64> = tr.confirmed().iter().map(|k| k.id).collect();
    assert_eq!(ids, [1, 2]);
    let ev = tr.step(6.0, &cam(), &[Vector2::new(60.0, 15.0)]).unwrap();
    assert!(
        ev.iter().all(|e| !matches!(e, TrackEvent::Born { .. })),
        "{ev:?}"
    );
    let c = tr.confirmed();
    assert!(
        c[0].estimate.mean[1] < 15.0 && c[1].estimate.mean[1] > 15.0,
        "{c:?}"
    );
    for k in 7..12 {
        let k = f64::from(k);
        tr.step(k, &cam(), &[b(k), a(k)]).unwrap();
    }
    let c = tr.confirmed();
    assert_eq!(c.len(), 2);
    assert!((c[0].estimate.mean.xy() - a(11.0)).norm() < 10.0, "{c:?}");
    assert!((c[1].estimate.mean.xy() - b(11.0)).norm() < 10.0, "{c:?}");
    assert!(tr.stats().clusters > 0 && tr.stats().capped == 0);
}

#[test]
fn a_jipda_tracker_adopts_a_gnn_trackers_tracks_with_their_ids() {
    let mut gnn = tracker(2, 3);
    let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
    for k in 0..4 {
        gnn.step(f64::from(k), &cam(), &[at(f64::from(k))]).unwrap();
    }
    let handover: Vec<_> = gnn
        .records()
        .into_iter()
        .zip(gnn.snapshot())
        .map(|(r, s)| (r, s.estimate))
        .collect();
    assert_eq!(handover[0].0.existence, None);
    let mut soft = jipda_tracker();
    soft.adopt(3.0, &handover).unwrap();
    assert_eq!(soft.tracks()[0].id, 1);
    assert_eq!(soft.tracks()[0].existence, Some(0.9));
    let ev = soft.step(4.0, &cam(), &[at(4.0)]).unwrap();
    assert!(matches!(ev[0], TrackEvent::Updated { id: 1, .. }), "{ev:?}");
    assert!(soft.snapshot()[0].existence.unwrap() > 0.99);
    // And back: GNN keeps the id and drops the existence.
    let back: Vec<_> = soft
        .records()
        .into_iter()
        .zip(soft.snapshot())
        .map(|(r, s)| (r, s.estimate))
        .collect();
    let mut gnn2 = tracker(2, 3);
    gnn2.adopt(4.0, &back).unwrap();
    assert_eq!((gnn2.tracks()[0].id, gnn2.tracks()[0].existence), (1, None));
    assert_eq!(gnn2.next_id(), 2);
}

/// The tracker of `association` (KF tracks, CV q = 0.25) on a one-group crossing scenario of the
/// group generator (10 m noise, Pd 0.9, 2 clutter detections a scan) from `seed`: the continuity
/// counts with a 20 m threshold.
fn crossing_swaps(seed: u64, association: Association) -> (usize, usize) {
    use crate::tracker::format::MultiScenario;
    use crate::tracker::generate::groups::{GroupConfig, Shape, generate};
    use crate::tracker::metrics::Continuity;
    let cfg = GroupConfig {
        shape: Shape::Crossing,
        groups: 1,
        clutter_rate: 2.0,
        ..GroupConfig::default()
    };
    let g = generate(seed, &cfg).unwrap();
    let m =
        MultiScenario::parse(&g.scenario_json, &g.measurements_jsonl, Some(&g.truth_csv)).unwrap();
    let mut tr = tracker(2, 4);
    tr.filter = GaussianFilter {
        filter: Extended,
        motion: ConstantVelocity::new(0.25),
    };
    tr.initiator = SinglePointInitiator::new(12.0, 50.0).unwrap();
    tr.config.deleter = Deleter::new(5, 1e5, 2).unwrap();
    tr.config.tentative_gater = Gater::chi2(0.95, 2).unwrap();
    tr.config.association = association;
    let sensor = Position::new(Geometry::planar(0.0), [10.0, 10.0]);
    let mut c = Continuity::new(20.0).unwrap();
    for s in &m.scans {
        let dets: Vec<Vector2<f64>> = s
            .detections
            .iter()
            .map(|d| Vector2::new(d.z[0], d.z[1]))
            .collect();
        tr.set_clutter_density(Some(
            2.0 / m.detection.as_ref().unwrap().region.unwrap().area(),
        ));
        tr.step(s.t, &sensor, &dets).unwrap();
        let tracks: Vec<(u64, Vector2<f64>)> = tr
            .confirmed()
            .iter()
            .map(|k| (k.id, k.estimate.mean.xy()))
            .collect();
        let truths: Vec<(usize, Vector2<f64>)> = m
            .truth_at(s.t)
            .into_iter()
            .map(|(i, x)| (i, Vector2::new(x[0], x[1])))
            .collect();
        c.add_scan(&truths, &tracks).unwrap();
    }
    let r = c.report();
    (r.swaps, r.id_switches)
}

fn mht_with(window: usize, leaves: usize, hysteresis: f64) -> Association {
    Association::Mht(
        Mht::new(
            DetectionModel::new(0.9, None).unwrap(),
            Existence::new(0.995, 0.1, 0.9, 0.01).unwrap(),
            window,
            leaves,
            100_000,
            100_000,
            hysteresis,
        )
        .unwrap(),
    )
}

/// Seed 8 of the one-group crossing: the targets are missed while they are less than 30 m apart
/// (scans 37, 39 and 44). GNN commits to the wrong detection for a track and swaps; the
/// multi-scan associator, which decides each scan two scans later, keeps both tracks.
#[test]
fn the_multi_scan_associator_resolves_a_crossing_gnn_gets_wrong() {
    use crate::tracker::format::MultiScenario;
    use crate::tracker::generate::groups::{GroupConfig, Shape, generate};
    let cfg = GroupConfig {
        shape: Shape::Crossing,
        groups: 1,
        clutter_rate: 2.0,
        ..GroupConfig::default()
    };
    let g = generate(8, &cfg).unwrap();
    let m =
        MultiScenario::parse(&g.scenario_json, &g.measurements_jsonl, Some(&g.truth_csv)).unwrap();
    let missed_close = m
        .scans
        .iter()
        .filter(|s| {
            let tr = m.truth_at(s.t);
            let close =
                tr.len() == 2 && (tr[0].1[0] - tr[1].1[0]).hypot(tr[0].1[1] - tr[1].1[1]) < 30.0;
            close
                && tr.iter().any(|(_, x)| {
                    !s.detections
                        .iter()
                        .any(|d| (d.z[0] - x[0]).hypot(d.z[1] - x[1]) < 35.0)
                })
        })
        .count();
    assert!(
        missed_close >= 2,
        "{missed_close} scans with a miss at the crossing"
    );
    let (gnn_swaps, _) = crossing_swaps(8, Association::Gnn);
    let (mht_swaps, mht_switches) = crossing_swaps(8, mht_with(3, 16, 0.0));
    assert!(gnn_swaps > 0, "GNN does not swap");
    assert_eq!((mht_swaps, mht_switches), (0, 0));
}

#[test]
fn the_multi_scan_associator_keeps_ids_and_reports_existence() {
    let mut tr = tracker(2, 3);
    tr.config.association = mht_with(3, 16, 0.0);
    let at = |k: f64| Vector2::new(10.0 * k, 5.0 * k);
    let ev = tr.step(0.0, &cam(), &[at(0.0)]).unwrap();
    assert_eq!(
        ev,
        vec![TrackEvent::Born {
            id: 1,
            detection: 0
        }]
    );
    tr.set_clutter_density(Some(1e-6));
    let ev = tr.step(1.0, &cam(), &[at(1.0)]).unwrap();
    assert!(
        matches!(
            ev[0],
            TrackEvent::Updated {
                id: 1,
                detection: 0,
                ..
            }
        ),
        "{ev:?}"
    );
    assert!(ev.contains(&TrackEvent::Confirmed { id: 1 }), "{ev:?}");
    for k in 2..6 {
        tr.step(f64::from(k), &cam(), &[at(f64::from(k))]).unwrap();
    }
    let c = tr.confirmed();
    assert_eq!(c.len(), 1);
    assert!(c[0].existence.unwrap() > 0.99);
    assert!((c[0].estimate.mean.xy() - at(5.0)).norm() < 5.0);
    // Its tracks go to a GNN tracker and come back with their ids.
    let handover: Vec<_> = tr
        .records()
        .into_iter()
        .zip(tr.snapshot())
        .map(|(r, s)| (r, s.estimate))
        .collect();
    let mut gnn = tracker(2, 3);
    gnn.adopt(5.0, &handover).unwrap();
    let ev = gnn.step(6.0, &cam(), &[at(6.0)]).unwrap();
    assert!(matches!(ev[0], TrackEvent::Updated { id: 1, .. }), "{ev:?}");
    let back: Vec<_> = gnn
        .records()
        .into_iter()
        .zip(gnn.snapshot())
        .map(|(r, s)| (r, s.estimate))
        .collect();
    tr.adopt(6.0, &back).unwrap();
    let ev = tr.step(7.0, &cam(), &[at(7.0)]).unwrap();
    assert!(matches!(ev[0], TrackEvent::Updated { id: 1, .. }), "{ev:?}");
    assert_eq!(tr.next_id(), 2);
    // Misses delete it by existence.
    let mut deleted = false;
    for k in 8..20 {
        let ev = tr.step(f64::from(k), &cam(), &[]).unwrap();
        deleted |= ev.contains(&TrackEvent::Deleted {
            id: 1,
            reason: DeleteReason::Misses,
        });
    }
    assert!(deleted && tr.tracks().is_empty());
    assert!(tr.stats().clusters > 0 && tr.stats().capped == 0);
}
