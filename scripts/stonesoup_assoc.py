#!/usr/bin/env python3
"""Stone Soup's data associators on Harrier's generated close groups, timed and scored like
Harrier's own (`harrier track-eval`).

For each scenario directory (written by `harrier track-eval --write DIR` or `harrier gen-multi DIR
--shape S`: FORMAT-MULTI.md, one planar position sensor) it runs three Stone Soup 1.9.1 trackers
tuned like Harrier's defaults, writes each one's tracks per scan as FORMAT-MULTI.md §4 estimate
lines, scores them with `harrier track-eval --score` (GOSPA c = 20 m, p = 2, alpha = 2, and the
continuity counts: the very same code as Harrier's figures), and prints the means:

- gnn: `MultiTargetTracker` + `GlobalNearestNeighbour` over a Mahalanobis `DistanceHypothesiser`
  gated at chi2_2(0.999), the missed distance at the gate;
- jpda: `MultiTargetMixtureTracker` + pyehm's `JPDAWithEHM2` over a `PDAHypothesiser` (the
  scenario's P_D, clutter density = detection.clutter_rate / region area, P_G = 0.999);
- mfa: `MFADataAssociator` (slide window 3) over `MFAHypothesiser(PDAHypothesiser(...))`, tracks
  as Gaussian mixtures of tagged components, the best component reported, in a tracking loop
  written here (Stone Soup has no MFA tracker).

All three: `KalmanPredictor`/`KalmanUpdater` (Stone Soup has no IMM) with the scenario's CV model
(q = motion.accel_std^2, the same exact discretisation as Harrier's), tracks started by a
`MultiMeasurementInitiator` (2 detections, a GNN over holding tracks gated at chi2_2(0.95), prior
velocity std 12 m/s as Harrier's `vel_std`; holding tracks dropped after 3 scans without an
update) from the detections no track took, and deleted after 5 scans without an update (Harrier's
`misses`). The time per scan is the wall time of the tracker's step (association, updates,
initiation, deletion), mean over the scans, and the process CPU time per scan (which other load
on a shared machine inflates less).

    eval "$(scripts/setup --env)"                          # the test venv (numpy, scipy)
    python3 -m pip install stonesoup==1.9.1 pyehm==2.2 ortools  # ad hoc: not in the CI lock
    harrier track-eval --seeds 1-10 --write /tmp/groups  # Harrier's figures + the scenarios
    python3 scripts/stonesoup_assoc.py --harrier target/release/harrier /tmp/groups/*

Stone Soup is slow on dense clutter (minutes per scenario on a shared 2-core machine): pass a
subset of the directories (BENCHMARKS.md says which were run).
"""
import argparse
import json
import math
import subprocess
import sys
import time
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

try:
    import stonesoup
    from scipy.stats import chi2
    from stonesoup.dataassociator.mfa import MFADataAssociator
    from stonesoup.dataassociator.neighbour import GlobalNearestNeighbour
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.gater.distance import DistanceGater
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.mfa import MFAHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                    ConstantVelocity)
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
    from stonesoup.types.detection import Detection
    from stonesoup.types.mixture import GaussianMixture
    from stonesoup.types.numeric import Probability
    from stonesoup.types.state import GaussianState, TaggedWeightedGaussianState
    from stonesoup.types.track import Track
    from stonesoup.types.update import GaussianMixtureUpdate
    from stonesoup.updater.kalman import KalmanUpdater
    from pyehm.plugins.stonesoup import JPDAWithEHM2
except ImportError as e:
    sys.exit(f"{e}: pip install stonesoup==1.9.1 pyehm==2.2 ortools")

T0 = datetime(2026, 11, 27)
TRACKERS = ("gnn", "jpda", "mfa")


def load(d):
    """The scenario's settings and its scans as (time, [z])."""
    sc = json.loads((d / "scenario.json").read_text())
    scans = {}
    for line in (d / "measurements.jsonl").read_text().splitlines():
        m = json.loads(line)
        scans.setdefault(m["t"], []).append(m["z"])
    times = [sc["time"]["t0"] + k * sc["time"]["dt"]
             for k in range(int(round((sc["time"]["t_end"] - sc["time"]["t0"]) / sc["time"]["dt"])) + 1)]
    return sc, [(t, scans.get(t, [])) for t in times]


class Scans:
    """The scans as a Stone Soup detector: (time, set of Detections)."""

    def __init__(self, scans, model):
        self.scans, self.model = scans, model

    def __iter__(self):
        for t, zs in self.scans:
            ts = T0 + timedelta(seconds=t)
            yield ts, {Detection(np.array(z, dtype=float).reshape(2, 1), timestamp=ts,
                                 measurement_model=self.model) for z in zs}


def components(sc):
    q = sc["motion"]["accel_std"] ** 2
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    std = sc["sensors"][0]["noise"]["std"]
    model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([s * s for s in std]))
    det = sc["detection"]
    r = det["region"]
    density = det["clutter_rate"] / ((r["max"][0] - r["min"][0]) * (r["max"][1] - r["min"][1]))
    predictor, updater = KalmanPredictor(transition), KalmanUpdater(model)
    return predictor, updater, model, det["pd"], density


def initiator(predictor, updater, model):
    gate = chi2.ppf(0.95, 2)
    hyp = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=gate)
    return MultiMeasurementInitiator(
        prior_state=GaussianState(np.zeros((4, 1)), np.diag([0.0, 144.0, 0.0, 144.0]), timestamp=T0),
        measurement_model=model,
        deleter=UpdateTimeStepsDeleter(3),
        data_associator=GlobalNearestNeighbour(DistanceGater(hyp, Mahalanobis(), gate)),
        updater=updater,
        min_points=2)


def track_line(t, tracks):
    out = []
    for tr in tracks:
        s = tr.state
        if isinstance(s, GaussianMixture):
            s = max(s.components, key=lambda c: c.weight)
        x = np.asarray(s.state_vector, dtype=float).ravel()
        out.append({"id": tr.harrier_id, "state": [x[0], x[2], 0.0, x[1], x[3], 0.0]})
    return {"t": t, "state": None, "tracks": out}


def ids(tracks, seen):
    for tr in tracks:
        if not hasattr(tr, "harrier_id"):
            tr.harrier_id = len(seen) + 1
            seen.add(tr.harrier_id)


def run_simple(kind, sc, scans):
    """gnn and jpda: Stone Soup's own trackers; (estimate lines, seconds per scan)."""
    predictor, updater, model, pd, density = components(sc)
    gate = chi2.ppf(0.999, 2)
    if kind == "gnn":
        hyp = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=gate)
        tracker = MultiTargetTracker(
            initiator=initiator(predictor, updater, model), deleter=UpdateTimeStepsDeleter(5),
            detector=Scans(scans, model), updater=updater,
            data_associator=GlobalNearestNeighbour(DistanceGater(hyp, Mahalanobis(), gate)))
    else:
        hyp = PDAHypothesiser(predictor, updater, clutter_spatial_density=density,
                              prob_detect=Probability(pd), prob_gate=Probability(0.999))
        tracker = MultiTargetMixtureTracker(
            initiator=initiator(predictor, updater, model), deleter=UpdateTimeStepsDeleter(5),
            detector=Scans(scans, model), updater=updater, data_associator=JPDAWithEHM2(hyp))
    lines, seen, spent, cpu = [], set(), 0.0, 0.0
    it = iter(tracker)
    for (t, _) in scans:
        start, start_cpu = time.perf_counter(), time.process_time()
        _, tracks = next(it)
        spent += time.perf_counter() - start
        cpu += time.process_time() - start_cpu
        ids(tracks, seen)
        lines.append(track_line(t, tracks))
    return lines, spent / len(scans), cpu / len(scans)


def run_mfa(sc, scans, window):
    """mfa: the MFA associator in a tracking loop; (estimate lines, seconds per scan)."""
    predictor, updater, model, pd, density = components(sc)
    hyp = MFAHypothesiser(PDAHypothesiser(predictor, updater, clutter_spatial_density=density,
                                          prob_detect=Probability(pd),
                                          prob_gate=Probability(0.999)))
    associator = MFADataAssociator(hyp, slide_window=window)
    init = initiator(predictor, updater, model)
    tracks, lines, seen, spent, cpu = set(), [], set(), 0.0, 0.0
    for (t, _), (ts, detections) in zip(scans, Scans(scans, model)):
        start, start_cpu = time.perf_counter(), time.process_time()
        associations = associator.associate(tracks, detections, ts)
        used = set()
        for track, hypotheses in associations.items():
            comps = []
            for h in hypotheses:
                comps.append(h.prediction if not h else updater.update(h))
            track.append(GaussianMixtureUpdate(components=comps, hypothesis=hypotheses))
            best = max(hypotheses, key=lambda h: h.prediction.weight)
            if best:
                used.add(best.measurement)
                track.last_hit = ts
        # Delete tracks whose best hypothesis has had no detection for 5 scans.
        tracks = {tr for tr in tracks if ts - tr.last_hit < timedelta(seconds=5 * sc["time"]["dt"])}
        for new in init.initiate(detections - used, ts):
            s = new.state
            comp = TaggedWeightedGaussianState(s.state_vector, s.covar, timestamp=ts,
                                               weight=Probability(1), tag=[])
            tr = Track([GaussianMixture([comp])])
            tr.last_hit = ts
            tracks.add(tr)
        spent += time.perf_counter() - start
        cpu += time.process_time() - start_cpu
        ids(tracks, seen)
        lines.append(track_line(t, tracks))
    return lines, spent / len(scans), cpu / len(scans)


def score(harrier, d, lines, out):
    out.write_text("".join(json.dumps(line) + "\n" for line in lines))
    r = subprocess.run([harrier, "track-eval", "--score", str(d), "--estimates", str(out)],
                       capture_output=True, text=True, check=True)
    return json.loads(r.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="+", type=Path, help="scenario directories")
    ap.add_argument("--harrier", default="target/release/harrier", help="the harrier binary")
    ap.add_argument("--trackers", default=",".join(TRACKERS))
    ap.add_argument("--window", type=int, default=3, help="MFA slide window")
    ap.add_argument("--json", action="store_true", help="one JSON line per scenario and tracker")
    args = ap.parse_args()
    rows = {}
    for d in args.dirs:
        sc, scans = load(d)
        shape = d.name.rsplit("-seed", 1)[0]
        for kind in args.trackers.split(","):
            if kind == "mfa":
                lines, per_scan, cpu = run_mfa(sc, scans, args.window)
            else:
                lines, per_scan, cpu = run_simple(kind, sc, scans)
            s = score(args.harrier, d, lines, d / f"stonesoup-{kind}.jsonl")
            s.update(dir=str(d), tracker=kind, ms_per_scan=1e3 * per_scan,
                     cpu_ms_per_scan=1e3 * cpu, stonesoup=stonesoup.__version__)
            if args.json:
                print(json.dumps(s), flush=True)
            else:
                print(f"{d.name} {kind}: GOSPA {s['gospa']:.2f} m, swaps {s['swaps']}, "
                      f"{1e3 * per_scan:.1f} ms/scan", file=sys.stderr, flush=True)
            rows.setdefault((shape, kind), []).append(s)
    if args.json:
        return
    print(f"Stone Soup {stonesoup.__version__}; GOSPA c = 20 m, p = 2 (mean over scans, then "
          "scenarios); counts summed")
    print("| shape | tracker | runs | GOSPA m | swaps | id switches | breaks | false tracks | "
          "confirmed ≤ 3 scans | worst delay | ms/scan | CPU ms/scan |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (shape, kind), ss in rows.items():
        n = len(ss)
        worst = [s["worst_delay"] for s in ss]
        print(f"| {shape} | {kind} | {n} | {sum(s['gospa'] for s in ss) / n:.2f} | "
              f"{sum(s['swaps'] for s in ss)} | {sum(s['id_switches'] for s in ss)} | "
              f"{sum(s['breaks'] for s in ss)} | {sum(s['false_tracks'] for s in ss)} | "
              f"{sum(s['within_3'] for s in ss)}/{sum(s['targets'] for s in ss)} | "
              f"{'never' if None in worst else max(worst)} | "
              f"{sum(s['ms_per_scan'] for s in ss) / n:.1f} | "
              f"{sum(s['cpu_ms_per_scan'] for s in ss) / n:.1f} |")


if __name__ == "__main__":
    main()
