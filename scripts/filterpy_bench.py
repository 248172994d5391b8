#!/usr/bin/env python3
"""Time FilterPy's KalmanFilter and IMMEstimator predict + update at dim_x = 6, dim_z = 2.

The same problem as the `kf/cv6_position2` benchmark of core/benches/filters.rs: the 3-D
constant-velocity model [x, y, z, vx, vy, vz] at dt = 0.1 s with acceleration spectral density
q = 1 m^2/s^3 (exactly discretised Q), measuring [x, y] with sigma = 5 m. FilterPy's update is the
Joseph form, like Harrier's.

The filter is fed measurements of a target flying straight and level, so its state stays bounded
however many steps are timed. Each repeat times `number` steps; the figure is the median over
repeats of the time per step (the minimum is printed too).

    python3 scripts/filterpy_bench.py            # human-readable
    python3 scripts/filterpy_bench.py --json     # one JSON object on stdout
"""
import argparse
import json
import statistics
import sys
import timeit

import numpy as np

try:
    import filterpy
    from filterpy.kalman import IMMEstimator, KalmanFilter
except ImportError:
    sys.exit("filterpy is not installed: pip install filterpy")

DT = 0.1
Q_SPECTRAL = 1.0
SIGMA = 5.0


def cv6_matrices(dt, q):
    """F and Q of the 3-D CV model, layout [x, y, z, vx, vy, vz] (BLK01 section 6.2.2)."""
    i3 = np.eye(3)
    f = np.block([[i3, dt * i3], [np.zeros((3, 3)), i3]])
    qm = q * np.block([[dt ** 3 / 3 * i3, dt ** 2 / 2 * i3], [dt ** 2 / 2 * i3, dt * i3]])
    return f, qm


def truth(k):
    t = k * DT
    return np.array([1500.0 + 12.0 * t, 800.0 + 13.5 * t, 120.0, 12.0, 13.5, 0.0])


def make_filter():
    kf = KalmanFilter(dim_x=6, dim_z=2)
    kf.F, kf.Q = cv6_matrices(DT, Q_SPECTRAL)
    kf.H = np.zeros((2, 6))
    kf.H[0, 0] = kf.H[1, 1] = 1.0
    kf.R = np.eye(2) * SIGMA ** 2
    kf.x = (truth(0) + np.array([20.0, -15.0, 5.0, 2.0, -1.5, 0.5])).reshape(6, 1)
    kf.P = np.diag([400.0, 400.0, 100.0, 25.0, 25.0, 4.0])
    return kf


def ct6_matrix(dt, omega):
    """F of a coordinated turn at rate omega in the horizontal plane (z straight), layout as cv6."""
    f, _ = cv6_matrices(dt, 0.0)
    s, c = np.sin(omega * dt), np.cos(omega * dt)
    f[0, 3], f[0, 4], f[1, 3], f[1, 4] = s / omega, -(1 - c) / omega, (1 - c) / omega, s / omega
    f[3, 3], f[3, 4], f[4, 3], f[4, 4] = c, -s, s, c
    return f


def make_imm():
    """IMM of three KFs (CV, right turn, left turn) as the `imm/imm3_cv6_position2` bench."""
    filters = []
    for omega in (None, -0.1, 0.1):
        kf = make_filter()
        if omega is not None:
            kf.F = ct6_matrix(DT, omega)
        filters.append(kf)
    mu = np.array([0.98, 0.01, 0.01])
    trans = np.array([[0.98, 0.01, 0.01], [0.01, 0.98, 0.01], [0.01, 0.01, 0.98]])
    return IMMEstimator(filters, mu, trans)


def time_filter(flt, args):
    n_steps = 1 + args.number * args.repeat
    zs = [truth(k)[:2].reshape(2, 1).copy() for k in range(1, n_steps + 1)]
    it = iter(zs)

    def step():
        flt.predict()
        flt.update(next(it))

    step()  # warm-up
    times = timeit.Timer(step).repeat(repeat=args.repeat, number=args.number)
    if not np.all(np.isfinite(flt.x)) or np.abs(flt.x[:2, 0] - truth(n_steps)[:2]).max() > 100.0:
        sys.exit("FilterPy state diverged during the benchmark")
    per_step_us = [t / args.number * 1e6 for t in times]
    return statistics.median(per_step_us), min(per_step_us)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--number", type=int, default=20000, help="steps per repeat")
    ap.add_argument("--repeat", type=int, default=7, help="repeats")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

    kf_median, kf_min = time_filter(make_filter(), args)
    imm_args = argparse.Namespace(number=max(1, args.number // 10), repeat=args.repeat)
    imm_median, imm_min = time_filter(make_imm(), imm_args)

    result = {
        "filter": "filterpy.kalman.KalmanFilter",
        "filterpy": filterpy.__version__,
        "numpy": np.__version__,
        "python": sys.version.split()[0],
        "dim_x": 6,
        "dim_z": 2,
        "number": args.number,
        "repeat": args.repeat,
        "median_us": kf_median,
        "min_us": kf_min,
        "imm_median_us": imm_median,
        "imm_min_us": imm_min,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"FilterPy {result['filterpy']} KalmanFilter predict+update (dim_x=6, dim_z=2), "
              f"numpy {result['numpy']}, Python {result['python']}:")
        print(f"  median {result['median_us']:.2f} us/step, min {result['min_us']:.2f} us/step "
              f"({args.repeat} repeats x {args.number} steps)")
        print(f"FilterPy IMMEstimator of 3 KalmanFilters: median {imm_median:.2f} us/step, "
              f"min {imm_min:.2f} us/step")


if __name__ == "__main__":
    main()
