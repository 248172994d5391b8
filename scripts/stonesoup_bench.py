#!/usr/bin/env python3
"""Time Stone Soup's Kalman and extended Kalman predict + update at 6 states / 2 measurements.

The same problems as the `kf/cv6_position2` and `ekf/cv6_range_bearing` benchmarks of
core/benches/filters.rs: the 3-D constant-velocity model at dt = 0.1 s with acceleration spectral
density q = 1 m^2/s^3 (Stone Soup's `CombinedLinearGaussianTransitionModel` of three
`ConstantVelocity(1.0)`, exactly discretised like Harrier's), the same truth, initial estimate and
covariance. Stone Soup orders the state [x, vx, y, vy, z, vz] where Harrier has
[x, y, z, vx, vy, vz]: the same numbers, permuted.

- kf: `KalmanPredictor` + `KalmanUpdater(use_joseph_cov=True)` (Joseph form, like Harrier's)
  with `LinearGaussian` measuring [x, y], sigma = 5 m.
- ekf: `ExtendedKalmanPredictor` + `ExtendedKalmanUpdater(use_joseph_cov=True)` with
  `CartesianToBearingRange` from the sensor of filters.rs, sigma = [0.005 rad, 5 m]. Stone Soup's
  range is horizontal (2-D) where Harrier's is the 3-D slant range, and Stone Soup differentiates
  this model numerically; both are one 2 x 6 Jacobian per update.

Stone Soup has no interacting-multiple-model predictor or updater (1.9.1), so there is no IMM
figure to set against `imm/imm3_cv6_position2`.

Stone Soup caches predictions by (prior, time), so each timed step starts from the previous
step's posterior: the filter runs on, fed measurements of a target flying straight and level (its
state stays bounded), and each step builds the `SingleHypothesis` the updater takes, as a Stone Soup
tracker does. Each repeat times `number` steps; the figure is the median over repeats of the time
per step (the minimum, and the median of the process CPU time, which other load on the machine
disturbs less, are printed too).

    python3 scripts/stonesoup_bench.py            # human-readable
    python3 scripts/stonesoup_bench.py --json     # one JSON object on stdout
"""
import argparse
import json
import statistics
import sys
import time
from datetime import datetime, timedelta

import numpy as np

try:
    import stonesoup
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                    ConstantVelocity)
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor, KalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import ExtendedKalmanUpdater, KalmanUpdater
except ImportError:
    sys.exit("stonesoup is not installed: pip install stonesoup==1.9.1")

DT = 0.1
Q_SPECTRAL = 1.0
SIGMA = 5.0
# Ground radar of filters.rs: position (m), range and bearing sigmas.
SENSOR = np.array([-200.0, -300.0, 2.0])
SIGMA_RANGE = 5.0
SIGMA_BEARING = 0.005
T0 = datetime(2026, 11, 23)
# Harrier's [x, y, z, vx, vy, vz] -> Stone Soup's [x, vx, y, vy, z, vz].
ORDER = [0, 3, 1, 4, 2, 5]


def truth(k):
    """Truth [x, y, z, vx, vy, vz] at step k, as filters.rs: 120 m up, 18 m/s to the north-east."""
    t = k * DT
    return np.array([1500.0 + 12.0 * t, 800.0 + 13.5 * t, 120.0, 12.0, 13.5, 0.0])


def initial():
    """The initial estimate of filters.rs, in Stone Soup's layout."""
    mean = truth(0) + np.array([20.0, -15.0, 5.0, 2.0, -1.5, 0.5])
    cov = np.diag([400.0, 400.0, 100.0, 25.0, 25.0, 4.0])
    return GaussianState(mean[ORDER].reshape(6, 1), cov[np.ix_(ORDER, ORDER)], timestamp=T0)


def transition():
    return CombinedLinearGaussianTransitionModel([ConstantVelocity(Q_SPECTRAL)] * 3)


def kf_problem():
    """Predictor, updater, and the measurement [x, y] of the truth at step k."""
    model = LinearGaussian(ndim_state=6, mapping=(0, 2), noise_covar=np.eye(2) * SIGMA ** 2)

    def z(k):
        return truth(k)[:2].reshape(2, 1), model

    return KalmanPredictor(transition()), KalmanUpdater(model, use_joseph_cov=True), z


def ekf_problem():
    """Predictor, updater, and the measurement [bearing, range] of the truth at step k."""
    model = CartesianToBearingRange(
        ndim_state=6, mapping=(0, 2),
        noise_covar=np.diag([SIGMA_BEARING ** 2, SIGMA_RANGE ** 2]),
        translation_offset=SENSOR[:2].reshape(2, 1))

    def z(k):
        d = truth(k)[:2] - SENSOR[:2]
        return np.array([[np.arctan2(d[1], d[0])], [np.hypot(d[0], d[1])]]), model

    return (ExtendedKalmanPredictor(transition()),
            ExtendedKalmanUpdater(model, use_joseph_cov=True), z)


def time_filter(problem, args):
    predictor, updater, z = problem
    n_steps = 1 + args.number * args.repeat
    detections = []
    for k in range(1, n_steps + 1):
        value, model = z(k)
        detections.append(Detection(value, timestamp=T0 + timedelta(seconds=k * DT),
                                    measurement_model=model))
    it = iter(detections)
    state = [initial()]

    def step():
        det = next(it)
        prediction = predictor.predict(state[0], timestamp=det.timestamp)
        state[0] = updater.update(SingleHypothesis(prediction, det))

    step()  # warm-up
    times, cpu = [], []
    for _ in range(args.repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        for _ in range(args.number):
            step()
        times.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    x = np.asarray(state[0].state_vector, dtype=float)[:, 0]
    if not np.all(np.isfinite(x)) or np.abs(x[[0, 2]] - truth(n_steps)[:2]).max() > 100.0:
        sys.exit("Stone Soup state diverged during the benchmark")
    per_step_us = [t / args.number * 1e6 for t in times]
    cpu_us = statistics.median(cpu) / args.number * 1e6
    return statistics.median(per_step_us), min(per_step_us), cpu_us


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--number", type=int, default=500, help="steps per repeat")
    ap.add_argument("--repeat", type=int, default=5, help="repeats")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

    kf_median, kf_min, kf_cpu = time_filter(kf_problem(), args)
    ekf_median, ekf_min, ekf_cpu = time_filter(ekf_problem(), args)

    result = {
        "filter": "stonesoup KalmanPredictor + KalmanUpdater",
        "stonesoup": stonesoup.__version__,
        "numpy": np.__version__,
        "python": sys.version.split()[0],
        "dim_x": 6,
        "dim_z": 2,
        "number": args.number,
        "repeat": args.repeat,
        "median_us": kf_median,
        "min_us": kf_min,
        "cpu_us": kf_cpu,
        "ekf_median_us": ekf_median,
        "ekf_min_us": ekf_min,
        "ekf_cpu_us": ekf_cpu,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"Stone Soup {result['stonesoup']} KalmanPredictor + KalmanUpdater (dim_x=6, "
              f"dim_z=2), numpy {result['numpy']}, Python {result['python']}:")
        print(f"  median {kf_median:.2f} us/step, min {kf_min:.2f} us/step, CPU {kf_cpu:.2f} "
              f"us/step ({args.repeat} repeats x {args.number} steps)")
        print(f"Stone Soup ExtendedKalmanPredictor + ExtendedKalmanUpdater, "
              f"CartesianToBearingRange: median {ekf_median:.2f} us/step, "
              f"min {ekf_min:.2f} us/step, CPU {ekf_cpu:.2f} us/step")


if __name__ == "__main__":
    main()
