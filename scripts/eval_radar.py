#!/usr/bin/env python3
"""Compare the radar estimators on the reference radar_bias scenarios and on freshly generated
seeds (scripts/gen_radar_bias.py), so that claims do not rest on one seed.

    python3 scripts/eval_radar.py [--seeds 1-12] [--harrier target/release/harrier]

Prints, per bias type, the reference-scenario position RMSE and the mean / median / max over the
generated seeds (reference trajectory, and randomised trajectories with --vary).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.environ.get("HARRIER_SHARED", os.path.join(HERE, "..", "..", "shared"))
ESTIMATORS = ["cdkf", "icdkf", "cdkf-bias"]


def rmse(harrier, scenario, est, out):
    r = subprocess.run([harrier, "replay", scenario, "-e", est, "-o", out, "--json"],
                       capture_output=True, text=True, check=True)
    return json.loads(r.stdout)["pos_rmse"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="1-12")
    ap.add_argument("--harrier", default=os.path.join(HERE, "..", "target", "release", "harrier"))
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="harrier-radar-")
    for vary, sub in ((False, "ref"), (True, "vary")):
        cmd = [sys.executable, os.path.join(HERE, "gen_radar_bias.py"), os.path.join(tmp, sub), "--seeds", a.seeds]
        subprocess.run(cmd + (["--vary"] if vary else []), check=True, capture_output=True)
    lo, hi = map(int, a.seeds.split("-"))
    out = os.path.join(tmp, "est.jsonl")
    print(f"{'bias':<7} {'estimator':<10} {'reference':>9}  {'seeds (ref. trajectory) mean/med/max':>36}  {'seeds (varied) mean/med/max':>28}")
    for bias in ("none", "abrupt", "markov"):
        for est in ESTIMATORS:
            ref = rmse(a.harrier, os.path.join(SHARED, "scenarios", f"radar_bias_{bias}"), est, out)
            cols = []
            for sub in ("ref", "vary"):
                v = np.array([rmse(a.harrier, os.path.join(tmp, sub, f"{bias}_{s}"), est, out) for s in range(lo, hi + 1)])
                cols.append(f"{v.mean():8.1f} {np.median(v):8.1f} {v.max():8.1f}")
            print(f"{bias:<7} {est:<10} {ref:9.1f}  {cols[0]:>36}  {cols[1]:>28}")


if __name__ == "__main__":
    main()
