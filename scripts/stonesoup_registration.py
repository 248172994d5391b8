#!/usr/bin/env python3
"""Stone Soup's bias updater (`GaussianBiasUpdater`, the unmerged `sensor_bias` branch of
dstl/Stone-Soup) on a `harrier gen-registration` scenario, for the comparison of BENCHMARKS.md.

    python3 scripts/stonesoup_registration.py DIR [--json]

The branch is not on PyPI; install it into a venv of its own from a clone:

    git -C Stone-Soup archive sensor_bias | tar -x -C /tmp/stonesoup-bias
    python3 -m venv /tmp/ss-venv
    SETUPTOOLS_SCM_PRETEND_VERSION=1.9.1.dev0 /tmp/ss-venv/bin/pip install /tmp/stonesoup-bias

What runs (the `mounting` case: both cameras' azimuth and elevation offsets, radar unbiased):
one track, Stone Soup's `ExtendedKalmanPredictor` with the scenario's CV model
(`motion.accel_std`), its `UnscentedKalmanUpdater` for the radar and, for each camera, a
`GaussianBiasUpdater` holding that camera's two offsets (prior N(0, (1 deg)^2) each, as Harrier's
default, constant up to a 1e-12 random walk) with a bias model wrapper that adds them to the
measurement — Harrier's offset model; the branch's wrappers are rotation, translation and time
offsets of its own sensor models. The measurement functions are Harrier's conventions (azimuth
clockwise from North, elevation, 3-D range; FORMAT.md section 1). The updater augments the
track with the bias for each update and keeps the bias's marginal afterwards: the cross-covariance
between the track and the bias is dropped after every update, where Harrier's registration keeps
it. Told which sensors and terms are biased (no latency, no radar bias states), it is closer to
Harrier's `told-model` variant than to its one tuning.

Prints the position RMSE from scoring.t_start on and each camera's offset errors at the end (deg).
"""
import argparse
import csv
import datetime
import json
import math
import os

import numpy as np
from stonesoup.base import Property
from stonesoup.models.measurement.bias import BiasModelWrapper
from stonesoup.models.measurement.nonlinear import NonLinearGaussianMeasurement
from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                ConstantVelocity, RandomWalk)
from stonesoup.predictor.kalman import ExtendedKalmanPredictor, KalmanPredictor
from stonesoup.types.angle import Bearing, Elevation
from stonesoup.types.array import StateVector, StateVectors
from stonesoup.types.detection import Detection
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import GaussianState, State
from stonesoup.types.track import Track
from stonesoup.updater.bias import GaussianBiasUpdater
from stonesoup.updater.kalman import UnscentedKalmanUpdater

T0 = datetime.datetime(2025, 1, 1)


class HarrierSensor(NonLinearGaussianMeasurement):
    """Harrier's `az_el` or `range_bearing` of a planar target [x, vx, y, vy] on z = plane_z."""
    kind: str = Property(doc="az_el or range_bearing")
    platform: np.ndarray = Property(doc="sensor position (ENU, m)")
    plane_z: float = Property(default=0.0)

    @property
    def ndim_meas(self):
        return 2

    def function(self, state, noise=False, **kwargs):
        out = []
        for sv in state.state_vector.view(StateVectors):
            d = np.array([float(sv[0, 0]), float(sv[2, 0]), self.plane_z]) - self.platform
            az = math.atan2(d[0], d[1])
            if self.kind == "az_el":
                z = [Bearing(az), Elevation(math.atan2(d[2], math.hypot(d[0], d[1])))]
            else:
                z = [float(np.linalg.norm(d)), Bearing(az)]
            out.append(StateVector(z))
        if noise:
            raise ValueError("noise-free use only")
        return out[0] if len(out) == 1 else StateVectors(out)


class OffsetBiasModelWrapper(BiasModelWrapper):
    """Harrier's offset model: the bias states added to the wrapped model's measurement."""

    def function(self, state, noise=False, **kwargs):
        out = []
        for sv in state.state_vector.view(StateVectors):
            z = self.measurement_model.function(State(sv[self.state_mapping, :]), noise=noise)
            out.append(StateVector([z[i, 0] + float(sv[b, 0])
                                    for i, b in enumerate(self.bias_mapping)]))
        return out[0] if len(out) == 1 else StateVectors(out)


def run(directory):
    with open(os.path.join(directory, "scenario.json")) as f:
        sc = json.load(f)
    plane_z = sc.get("plane_z") or 0.0
    q = sc["motion"]["accel_std"] ** 2
    std = {s["id"]: np.array(s["noise"]["std"]) for s in sc["sensors"]}
    kind = {s["id"]: s["kind"] for s in sc["sensors"]}
    p = sc["prior"]
    prior = GaussianState(StateVector([p["state"][0], p["state"][3], p["state"][1], p["state"][4]]),
                          np.array(p["cov"])[np.ix_([0, 2, 1, 3], [0, 2, 1, 3])], timestamp=T0)
    predictor = ExtendedKalmanPredictor(CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(q), ConstantVelocity(q)]))
    updater = UnscentedKalmanUpdater(None)
    bias_updaters, bias_tracks = {}, {}
    for cam in (s for s in std if kind[s] == "az_el"):
        sigma = math.radians(1.0)
        track = Track([GaussianState(StateVector([0.0, 0.0]), np.diag([sigma ** 2] * 2))])
        bias_tracks[cam] = track
        bias_updaters[cam] = GaussianBiasUpdater(
            bias_track=track,
            bias_predictor=KalmanPredictor(CombinedLinearGaussianTransitionModel(
                [RandomWalk(1e-12), RandomWalk(1e-12)])),
            bias_model_wrapper=OffsetBiasModelWrapper,
            updater=UnscentedKalmanUpdater(None))
    track = Track([prior])
    with open(os.path.join(directory, "measurements.jsonl")) as f:
        lines = [json.loads(x) for x in f if x.strip()]
    estimates = []
    for m in lines:
        t = T0 + datetime.timedelta(seconds=m["t"])
        model = HarrierSensor(ndim_state=4, mapping=(0, 2), noise_covar=np.diag(std[m["sensor"]] ** 2),
                              kind=m["kind"], platform=np.array(m["platform"]["pos"]),
                              plane_z=plane_z)
        z = m["z"]
        zv = StateVector([Bearing(z[0]), Elevation(z[1])]) if m["kind"] == "az_el" \
            else StateVector([z[0], Bearing(z[1])])
        detection = Detection(zv, timestamp=t, measurement_model=model)
        prediction = predictor.predict(track.state, timestamp=t)
        hypothesis = SingleHypothesis(prediction, detection)
        if m["sensor"] in bias_updaters:
            post = bias_updaters[m["sensor"]].update([hypothesis])[0]
        else:
            post = updater.update(hypothesis)
        track.append(post)
        if estimates and estimates[-1][0] == m["t"]:
            estimates[-1] = (m["t"], post.state_vector)
        else:
            estimates.append((m["t"], post.state_vector))
    truth = {}
    with open(os.path.join(directory, "truth.csv")) as f:
        for r in csv.DictReader(f):
            truth[round(float(r["t"]), 6)] = (float(r["x"]), float(r["y"]))
    t_start = sc.get("scoring", {}).get("t_start", 0.0)
    err = [math.hypot(sv[0, 0] - truth[round(t, 6)][0], sv[2, 0] - truth[round(t, 6)][1])
           for t, sv in estimates if t >= t_start]
    bias_truth = {}
    with open(os.path.join(directory, "bias_truth.csv")) as f:
        for r in csv.DictReader(f):
            bias_truth[(r["sensor"], r["term"])] = float(r["value"])
    final = {}
    for cam, track in bias_tracks.items():
        b = track.state_vector
        final[cam] = [math.degrees(float(b[i, 0]) - bias_truth.get((cam, f"offset{i}"), 0.0))
                      for i in range(2)]
    return {"scenario": sc["name"], "pos_rmse": float(np.sqrt(np.mean(np.square(err)))),
            "final_offset_error_deg": final}


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    out = run(a.dir)
    if a.json:
        print(json.dumps(out))
    else:
        print(f"{out['scenario']}: pos RMSE {out['pos_rmse']:.3f} m; final offset errors (deg) "
              + ", ".join(f"{c} az {e[0]:+.4f} el {e[1]:+.4f}"
                          for c, e in out["final_offset_error_deg"].items()))


if __name__ == "__main__":
    main()
