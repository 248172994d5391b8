#!/usr/bin/env python3
"""Estimators against their baselines on harrier-sim recordings: each preset is recorded for
several seeds (`harrier-sim record`), every estimator is replayed on the same recordings
(`harrier replay --json`), and the position RMSE and NEES-95 %-ok are summarised.

    python3 scripts/eval_sim.py [--seeds 1-8] [--bin target/release]

Needs release builds of `harrier` and `harrier-sim` (cargo build --release). Prints a Markdown
table (mean and median over the seeds) for BENCHMARKS.md.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))

# (preset, vehicles, duration s, estimators: baseline first)
CASES = [
    ("cimm-road", 3, 700, ["kf", "imm", "cimm", "cimm-fusion"]),
    ("cimm-road", 1, 700, ["kf", "imm", "cimm"]),
    ("radar", 1, 300, ["ekf", "cdkf", "icdkf", "cdkf-bias"]),
    ("radar-abrupt", 1, 300, ["ekf", "cdkf", "icdkf", "cdkf-bias"]),
    ("radar-markov", 1, 300, ["ekf", "cdkf", "icdkf", "cdkf-bias"]),
    ("leader", 1, 120, ["mpekf", "mpekf-nn"]),
]


def median(v):
    s = sorted(v)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="1-8")
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "target", "release"))
    a = ap.parse_args()
    lo, hi = map(int, a.seeds.split("-"))
    sim, harrier = os.path.join(a.bin, "harrier-sim"), os.path.join(a.bin, "harrier")
    tmp = tempfile.mkdtemp(prefix="harrier-evalsim-")
    print(f"| preset | UAVs | estimator | pos RMSE mean (m) | median | NEES-95 % ok mean | seeds |")
    print("|---|---|---|---|---|---|---|")
    for preset, count, duration, estimators in CASES:
        dirs = []
        for seed in range(lo, hi + 1):
            d = os.path.join(tmp, f"{preset}-{count}-{seed}")
            subprocess.run([sim, "record", "--scenario", preset, "--seed", str(seed), "--count", str(count),
                            "--duration", str(duration), "--out", d], check=True, capture_output=True)
            dirs.append(d)
        for est in estimators:
            rmse, ok = [], []
            for d in dirs:
                r = subprocess.run([harrier, "replay", d, "-e", est, "-o", os.path.join(d, f"{est}.jsonl"), "--json"],
                                   capture_output=True, text=True)
                if r.returncode != 0:
                    sys.exit(f"{est} on {d}: {r.stderr.strip()}")
                s = json.loads(r.stdout)
                rmse.append(s["pos_rmse"])
                ok.append(s["nees"]["frac_within_95"] if s.get("nees") else float("nan"))
            print(f"| {preset} | {count} | `{est}` | {sum(rmse) / len(rmse):.2f} | {median(rmse):.2f} | "
                  f"{sum(ok) / len(ok):.3f} | {lo}–{hi} |", flush=True)


if __name__ == "__main__":
    main()
