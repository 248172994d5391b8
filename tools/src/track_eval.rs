//! `harrier track-eval`: the multi-target tracker's associators side by side on generated close
//! groups of turning ground targets (harrier-core's `generate::groups`), scored per scan with
//! GOSPA (cut-off c, p = 2, α = 2) and the track-continuity counts, and timed; or
//! (`--score`) one estimates file of any tracker (Stone Soup's, `scripts/stonesoup_assoc.py`)
//! scored the same way.
//!
//! ```not_rust
//! harrier track-eval --seeds 1-10                       # every shape, gnn/jipda/mht, imm tracks
//! harrier track-eval --seeds 1-10 --write /tmp/groups   # also write the scenarios
//! harrier track-eval --trackers oracle/imm,jipda/imm    # against known association
//! harrier track-eval --score /tmp/groups/crossing-seed1 --estimates ss-jpda.jsonl
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context as _, bail};
use harrier_core::scenario::{Estimate, ScenarioData};
use harrier_core::tracker::format::MultiScenario;
use harrier_core::tracker::generate::{groups, position_line};
use harrier_core::tracker::metrics::{Continuity, gospa};
use harrier_engine::Params;
use nalgebra::Vector2;
use serde::Serialize;

use crate::gen_multi::{shape_config, write_generated};
use crate::replay::{self, TrackerChoice};

/// `harrier track-eval`'s options.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalArgs {
    /// Seeds: `1-10` or `1,4,7`.
    #[arg(long, default_value = "1-10")]
    pub seeds: String,
    /// Scenario shapes: `crossing`, `parallel`, `opposing`, `mixed` (10 clutter detections a
    /// scan), `dense` (mixed, 50 a scan).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "crossing,parallel,opposing,dense"
    )]
    pub shapes: Vec<String>,
    /// Trackers as `ASSOCIATOR/TRACK_FILTER` (see `harrier estimators`); the associator
    /// `oracle` is the known-association bound (each target tracked alone on its own
    /// detections by `gnn`).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "gnn/ekf,gnn/imm,jipda/imm,mht/imm"
    )]
    pub trackers: Vec<String>,
    /// Tracker parameter, `name=value` (repeatable), for every tracker that takes it.
    #[arg(long = "param", short = 'p', value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Clutter detections per scan instead of the shape's.
    #[arg(long)]
    pub clutter: Option<f64>,
    /// GOSPA cut-off c (m); also the distance within which a track counts as following a
    /// target for the continuity counts.
    #[arg(long, default_value_t = 20.0)]
    pub cutoff: f64,
    /// Write each generated scenario into DIR/SHAPE-seedN/.
    #[arg(long, value_name = "DIR")]
    pub write: Option<PathBuf>,
    /// Print JSON (one object per shape and tracker) instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Score this scenario directory's truth against `--estimates` instead (FORMAT-MULTI.md §4
    /// lines, any tracker's), printed as JSON.
    #[arg(long, value_name = "SCENARIO_DIR", requires = "estimates")]
    pub score: Option<PathBuf>,
    /// The estimates file `--score` scores.
    #[arg(long, value_name = "FILE")]
    pub estimates: Option<PathBuf>,
}

/// One run's figures: GOSPA means over the scans and the continuity counts.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct MultiScore {
    /// Scans scored (those with an estimate line).
    pub scans: usize,
    /// Mean GOSPA (m).
    pub gospa: f64,
    /// Mean localisation part of GOSPA^p (m²).
    pub localisation: f64,
    /// Mean missed-target part (m²).
    pub missed: f64,
    /// Mean false-track part (m²).
    pub false_part: f64,
    /// A track moved from one target to another.
    pub swaps: usize,
    /// Swaps back to the target the track had left at most 3 scans before.
    pub swaps_undone: usize,
    /// A target's track changed.
    pub id_switches: usize,
    /// A target lost its track.
    pub breaks: usize,
    /// Confirmed tracks that followed a target in fewer than half of their scans.
    pub false_tracks: usize,
    /// Confirmed tracks.
    pub tracks: usize,
    /// Targets.
    pub targets: usize,
    /// Targets confirmed within 3 scans of their first (delay ≤ 2).
    pub within_3: usize,
    /// Largest confirmation delay (scans), `None` when a target was never confirmed.
    pub worst_delay: Option<usize>,
    /// Per target (index into the scenario's `targets`): its confirmation delay (scans), `None`
    /// when never confirmed.
    #[serde(skip)]
    pub delays: BTreeMap<usize, Option<usize>>,
}

/// Scores the estimate lines of a multi-target tracker against `m`'s truth: GOSPA with cut-off
/// `c` and p = 2 per scored scan, and the continuity counts with association threshold `c`.
pub fn score(m: &MultiScenario, estimates: &[Estimate], c: f64) -> anyhow::Result<MultiScore> {
    let mut continuity = Continuity::new(c)?;
    let mut out = MultiScore::default();
    for e in estimates {
        let tracks: Vec<(u64, Vector2<f64>)> = e
            .extra
            .get("tracks")
            .and_then(|v| v.as_array())
            .context("an estimate line without \"tracks\"")?
            .iter()
            .map(|k| {
                let id = k["id"].as_u64().context("a track without an id")?;
                let s = &k["state"];
                let xy = (s[0].as_f64(), s[1].as_f64());
                match xy {
                    (Some(x), Some(y)) => Ok((id, Vector2::new(x, y))),
                    _ => bail!("track {id} without a state"),
                }
            })
            .collect::<anyhow::Result<_>>()?;
        let truths: Vec<(usize, Vector2<f64>)> = m
            .truth_at(e.t)
            .into_iter()
            .map(|(i, s)| (i, Vector2::new(s[0], s[1])))
            .collect();
        continuity.add_scan(&truths, &tracks)?;
        let x: Vec<_> = tracks.iter().map(|k| k.1).collect();
        let y: Vec<_> = truths.iter().map(|k| k.1).collect();
        let g = gospa(&x, &y, c, 2.0)?;
        out.scans += 1;
        out.gospa += g.gospa;
        out.localisation += g.localisation;
        out.missed += g.missed;
        out.false_part += g.false_tracks;
    }
    let n = out.scans.max(1) as f64;
    out.gospa /= n;
    out.localisation /= n;
    out.missed /= n;
    out.false_part /= n;
    let r = continuity.report();
    out.swaps = r.swaps;
    out.swaps_undone = r.swaps_undone;
    out.id_switches = r.id_switches;
    out.breaks = r.breaks;
    out.false_tracks = r.false_tracks;
    out.tracks = r.tracks;
    out.targets = r.confirmation_delays.len();
    out.within_3 = r
        .confirmation_delays
        .values()
        .filter(|d| d.is_some_and(|d| d <= 2))
        .count();
    out.worst_delay = r
        .confirmation_delays
        .values()
        .try_fold(0, |w, d| d.map(|d| w.max(d)));
    out.delays = r.confirmation_delays;
    Ok(out)
}

/// [`score`] against the truth of the scenario directory `dir`, `None` when it has no
/// multi-target truth (no `truth.csv`, or a scenario without `targets`).
pub fn score_dir(
    dir: &std::path::Path,
    estimates: &[Estimate],
    c: f64,
) -> anyhow::Result<Option<MultiScore>> {
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).ok();
    let (Some(sc), Some(meas), Some(truth)) = (
        read("scenario.json"),
        read("measurements.jsonl"),
        read("truth.csv"),
    ) else {
        return Ok(None);
    };
    let Ok(m) = MultiScenario::parse(&sc, &meas, Some(&truth)) else {
        return Ok(None);
    };
    score(&m, estimates, c).map(Some)
}

/// One line of a [`MultiScore`] with cut-off `c`.
pub fn summary(s: &MultiScore, c: f64) -> String {
    format!(
        "GOSPA (c = {c} m, p = 2) {:.2} m over {} scans; swaps {}, id switches {}, breaks {}, \
         false tracks {} of {}; {} of {} targets confirmed within 3 scans, worst delay {}",
        s.gospa,
        s.scans,
        s.swaps,
        s.id_switches,
        s.breaks,
        s.false_tracks,
        s.tracks,
        s.within_3,
        s.targets,
        s.worst_delay.map_or("never".into(), |d| d.to_string())
    )
}

/// `1-10` or `1,4,7`.
pub fn parse_seeds(s: &str) -> anyhow::Result<Vec<u64>> {
    let mut out = Vec::new();
    for part in s.split(',') {
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b): (u64, u64) = (a.trim().parse()?, b.trim().parse()?);
                if a > b {
                    bail!("seed range {part:?} is empty");
                }
                out.extend(a..=b);
            }
            None => out.push(part.trim().parse()?),
        }
    }
    Ok(out)
}

/// The figures of one tracker on one shape over the seeds.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Row {
    /// Shape name.
    pub shape: String,
    /// `ASSOCIATOR/TRACK_FILTER`.
    pub tracker: String,
    /// Seeds run.
    pub seeds: usize,
    /// Mean over the seeds of each run's mean GOSPA (m).
    pub gospa: f64,
    /// Summed over the seeds.
    pub swaps: usize,
    /// Summed over the seeds.
    pub swaps_undone: usize,
    /// Summed over the seeds.
    pub id_switches: usize,
    /// Summed over the seeds.
    pub breaks: usize,
    /// Summed over the seeds.
    pub false_tracks: usize,
    /// Summed over the seeds.
    pub targets: usize,
    /// Summed over the seeds.
    pub within_3: usize,
    /// Targets detected at least twice in their first three scans (that a rule needing two
    /// detections can confirm within three scans at all), summed over the seeds.
    pub confirmable: usize,
    /// Of those, confirmed within 3 scans, summed over the seeds.
    pub confirmable_within_3: usize,
    /// Largest confirmation delay over the seeds, `None` when a target was never confirmed.
    pub worst_delay: Option<usize>,
    /// Mean wall time per scan (ms), the tracker only.
    pub ms_per_scan: f64,
    /// Clusters whose exact solution hit its bound (JIPDA, MHT), summed.
    pub capped: u64,
}

/// Runs `harrier track-eval`.
pub fn run(args: &EvalArgs) -> anyhow::Result<()> {
    if let (Some(dir), Some(est)) = (&args.score, &args.estimates) {
        let text = std::fs::read_to_string(est).with_context(|| est.display().to_string())?;
        let estimates: Vec<Estimate> = text
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(serde_json::from_str)
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}: not estimate lines", est.display()))?;
        let s = score_dir(dir, &estimates, args.cutoff)?
            .with_context(|| format!("{}: no multi-target truth", dir.display()))?;
        println!("{}", serde_json::to_string(&s)?);
        return Ok(());
    }
    let rows = evaluate(args)?;
    if args.json {
        for r in &rows {
            println!("{}", serde_json::to_string(r)?);
        }
        return Ok(());
    }
    println!(
        "seeds {}, GOSPA c = {} m, p = 2, α = 2 (mean over scans, then seeds); counts summed over \
         the seeds",
        args.seeds, args.cutoff
    );
    println!(
        "| shape | tracker | GOSPA m | swaps | undone ≤ 3 scans | id switches | breaks | false \
         tracks | confirmed ≤ 3 scans | of the confirmable | worst delay | ms/scan | capped |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {} | {:.2} | {} | {} | {} | {} | {} | {}/{} | {}/{} | {} | {:.3} | {} |",
            r.shape,
            r.tracker,
            r.gospa,
            r.swaps,
            r.swaps_undone,
            r.id_switches,
            r.breaks,
            r.false_tracks,
            r.within_3,
            r.targets,
            r.confirmable_within_3,
            r.confirmable,
            r.worst_delay.map_or("never".into(), |d| d.to_string()),
            r.ms_per_scan,
            r.capped
        );
    }
    Ok(())
}

/// The rows of `harrier track-eval` (every shape × tracker of `args`, over its seeds), writing
/// the scenarios when `args.write` says so.
pub fn evaluate(args: &EvalArgs) -> anyhow::Result<Vec<Row>> {
    let seeds = parse_seeds(&args.seeds)?;
    let params = Params::parse(&args.params)?;
    let trackers: Vec<(String, TrackerChoice)> = args
        .trackers
        .iter()
        .map(|t| {
            let (a, f) = t.split_once('/').unwrap_or((t.as_str(), "imm"));
            (
                format!("{a}/{f}"),
                TrackerChoice {
                    filter: f.into(),
                    associator: a.into(),
                    register: false,
                },
            )
        })
        .collect();
    let mut rows = Vec::new();
    for shape in &args.shapes {
        let mut cfg = shape_config(shape)?;
        if let Some(c) = args.clutter {
            cfg.clutter_rate = c;
        }
        let mut by_tracker: BTreeMap<usize, Row> = BTreeMap::new();
        for &seed in &seeds {
            let g = groups::generate(seed, &cfg)?;
            if let Some(dir) = &args.write {
                write_generated(&dir.join(format!("{shape}-seed{seed}")), &g)?;
            }
            let m =
                MultiScenario::parse(&g.scenario_json, &g.measurements_jsonl, Some(&g.truth_csv))?;
            let data = ScenarioData::parse(&g.scenario_json, &g.measurements_jsonl, None)?;
            // The confirmable targets, as indices into the scenario's `targets` (`T{i}`).
            let confirmable: Vec<usize> = g
                .confirmable()
                .into_iter()
                .filter_map(|i| {
                    let id = format!("T{i}");
                    m.targets.iter().position(|t| t.id == id)
                })
                .collect();
            for (i, (name, choice)) in trackers.iter().enumerate() {
                let report = if choice.associator == ORACLE {
                    known_association(&g, &data, &choice.filter, &params)
                } else {
                    replay::run_tracker(&data, choice, &taken_by(choice, &params))
                        .map_err(anyhow::Error::from)
                }
                .with_context(|| format!("{name} on {shape} seed {seed}"))?;
                let s = score(&m, &report.estimates, args.cutoff)?;
                let r = by_tracker.entry(i).or_insert_with(|| Row {
                    shape: shape.clone(),
                    tracker: name.clone(),
                    worst_delay: Some(0),
                    ..Row::default()
                });
                r.seeds += 1;
                r.gospa += s.gospa;
                r.swaps += s.swaps;
                r.swaps_undone += s.swaps_undone;
                r.id_switches += s.id_switches;
                r.breaks += s.breaks;
                r.false_tracks += s.false_tracks;
                r.targets += s.targets;
                r.within_3 += s.within_3;
                r.confirmable += confirmable.len();
                r.confirmable_within_3 += confirmable
                    .iter()
                    .filter(|k| s.delays.get(k).copied().flatten().is_some_and(|d| d <= 2))
                    .count();
                r.worst_delay = r.worst_delay.zip(s.worst_delay).map(|(a, b)| a.max(b));
                r.ms_per_scan += 1e3 * report.elapsed.as_secs_f64() / m.scans.len() as f64;
                r.capped += report.association.map_or(0, |a| a.capped);
            }
        }
        for mut r in by_tracker.into_values() {
            let n = r.seeds.max(1) as f64;
            r.gospa /= n;
            r.ms_per_scan /= n;
            rows.push(r);
        }
    }
    Ok(rows)
}

/// The associator name of the known-association bound ([`known_association`]).
const ORACLE: &str = "oracle";

/// The known-association bound: every target tracked alone on its own detections (the labels
/// the generator keeps, [`Generated::origins`](harrier_core::tracker::generate::Generated)), by
/// the `gnn` tracker with the track filter `filter` — no clutter, no neighbour, nothing to
/// associate — and the tracks of all the targets reported together at each scan. What is left of
/// the swaps and breaks is what the track filter's errors cost against the scoring's threshold,
/// whatever the associator. So that every scan of a target's life is stepped (a coasting
/// track is reported), a scan that missed the target gets one decoy detection 100 km from
/// every other, which starts a tentative track that is never confirmed.
fn known_association(
    g: &harrier_core::tracker::generate::Generated,
    data: &ScenarioData,
    filter: &str,
    params: &Params,
) -> anyhow::Result<replay::ReplayReport> {
    let lines: Vec<&str> = g.measurements_jsonl.lines().collect();
    anyhow::ensure!(
        lines.len() == g.origins.len(),
        "{} measurement lines, {} origins",
        lines.len(),
        g.origins.len()
    );
    let choice = TrackerChoice {
        filter: filter.into(),
        associator: "gnn".into(),
        register: false,
    };
    let params = taken_by(&choice, params);
    let targets: std::collections::BTreeSet<usize> = g.detected.iter().map(|d| d.1).collect();
    // Per scan time (µs), the tracks of every target's run.
    let key = |t: f64| (t * 1e6).round() as i64;
    let mut scans: BTreeMap<i64, Vec<serde_json::Value>> = data
        .groups()
        .into_iter()
        .map(|(t, _)| (key(t), Vec::new()))
        .collect();
    let mut elapsed = std::time::Duration::ZERO;
    for &target in &targets {
        let mut own = String::new();
        let mut decoy = 0.0;
        let mut hits = lines
            .iter()
            .zip(&g.origins)
            .filter(|(_, o)| **o == Some(target))
            .map(|(l, _)| *l)
            .peekable();
        for &(t, _, hit) in g.detected.iter().filter(|d| d.1 == target) {
            if hit {
                let l = hits.next().context("a detection without its line")?;
                own.push_str(l);
            } else {
                decoy += 1e5;
                own.push_str(&position_line(t, [1e7 + decoy, 1e7]));
            }
            own.push('\n');
        }
        let data = ScenarioData::parse(&g.scenario_json, &own, None)?;
        let report = replay::run_tracker(&data, &choice, &params)?;
        elapsed += report.elapsed;
        for e in report.estimates {
            let tracks = e.extra.get("tracks").and_then(|v| v.as_array()).cloned();
            for mut k in tracks.into_iter().flatten() {
                let id = k["id"].as_u64().context("a track without an id")?;
                k["id"] = serde_json::json!(id + (target as u64 + 1) * 1_000_000);
                scans.entry(key(e.t)).or_default().push(k);
            }
        }
    }
    let estimates = scans
        .into_iter()
        .map(|(t, tracks)| {
            let mut e = Estimate {
                t: t as f64 * 1e-6,
                ..Estimate::default()
            };
            e.extra
                .insert("tracks".into(), serde_json::Value::Array(tracks));
            e
        })
        .collect();
    Ok(replay::ReplayReport {
        estimates,
        measurements: lines.len(),
        skipped_nonfinite: 0,
        rejected: Vec::new(),
        score: None,
        elapsed,
        association: None,
    })
}

/// The parameters of `params` that `choice`'s track filter or associator takes.
fn taken_by(choice: &TrackerChoice, params: &Params) -> Params {
    use harrier_engine::registry::{ASSOCIATORS, TRACK_FILTERS};
    let known: Vec<&str> = TRACK_FILTERS
        .iter()
        .filter(|f| f.name == choice.filter)
        .flat_map(|f| f.params.iter())
        .chain(
            ASSOCIATORS
                .iter()
                .filter(|a| a.name == choice.associator)
                .flat_map(|a| a.params.iter()),
        )
        .map(|p| p.0)
        .collect();
    params
        .names()
        .filter(|n| known.contains(n))
        .fold(Params::default(), |p, n| p.with(n, params.get(n, 0.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Seeds 1–3 of `shape` with `trackers`, as JSON.
    fn args(shape: &str, trackers: &[&str]) -> EvalArgs {
        EvalArgs {
            seeds: "1-3".into(),
            shapes: vec![shape.into()],
            trackers: trackers.iter().map(|t| t.to_string()).collect(),
            params: Vec::new(),
            clutter: None,
            cutoff: 20.0,
            write: None,
            json: true,
            score: None,
            estimates: None,
        }
    }

    /// The confirmable targets are found in the scenario (their ids mapped to its `targets`):
    /// every target confirmed within 3 scans that is not confirmable is one of the few the
    /// generator detected at most once in their first three scans.
    #[test]
    fn the_confirmable_targets_are_counted() {
        let rows = evaluate(&args("crossing", &["gnn/ekf"])).expect("rows");
        let [r] = rows.as_slice() else {
            panic!("{rows:?}")
        };
        assert_eq!((r.seeds, r.targets), (3, 24), "{r:?}");
        assert!(r.confirmable > 20 && r.confirmable <= r.targets, "{r:?}");
        assert!(
            r.confirmable_within_3 <= r.within_3.min(r.confirmable),
            "{r:?}"
        );
        assert!(
            r.confirmable_within_3 + (r.targets - r.confirmable) >= r.within_3,
            "{r:?}"
        );
    }

    /// The known-association bound tracks each target on its own detections: no false track,
    /// no swap on close parallel targets, as many targets confirmed on time as GNN and a lower
    /// GOSPA than GNN's with the same track filter (misaligned labels would give neither).
    #[test]
    fn the_known_association_bound_tracks_each_target_alone() {
        let rows = evaluate(&args("parallel", &["oracle/imm", "gnn/imm"])).expect("rows");
        let [oracle, gnn] = rows.as_slice() else {
            panic!("{rows:?}")
        };
        assert_eq!((oracle.false_tracks, oracle.swaps), (0, 0), "{oracle:?}");
        assert!(gnn.false_tracks > 0 && gnn.swaps > 0, "{gnn:?}");
        assert!(
            oracle.confirmable_within_3 >= gnn.confirmable_within_3,
            "{oracle:?} {gnn:?}"
        );
        assert!(oracle.gospa < 0.9 * gnn.gospa, "{oracle:?} {gnn:?}");
    }
}
