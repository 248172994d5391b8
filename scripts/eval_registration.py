#!/usr/bin/env python3
"""The sensor-registration figures of BENCHMARKS.md: `harrier replay -e registration` against its
baselines on `harrier gen-registration` scenarios, several seeds per case.

    python3 scripts/eval_registration.py [--seeds 1-8] [--duration 600] [--harrier PATH] [--json]
    python3 scripts/eval_registration.py --estimator tracker [--track-filter ekf]   # the live one

For every seed and case (FORMAT-REGISTRATION.md section 5) it writes the scenario variants into
--out (default a temporary directory), replays them and scores the estimates against truth.csv
and bias_truth.csv:

* `registration` on the `deployment` variant: THE estimator, one tuning (every sensor with
  Harrier's default bias model, whatever the case);
* the baselines: `registration` on `told-bias` (the measurements with the true bias taken out: a
  filter told the true bias; no bias state, the same EKF), on `told-model` (every biased term with
  its true model, e.g. a Gauss-Markov term's sigma and tau, but not its values), `ekf` on the
  deployment data (no registration at all);
* for `mounting`, the unbiased run is the `none` case of the same seed (the same noise).

Bias figures: the error of each term from --from seconds on (RMS over scans and seeds) against the
square root of its posterior Cramer-Rao bound (scripts/registration_crlb.py on the same scenario,
RMS over the same scans and seeds); bias NEES per sensor block against the chi-square 95 % bound;
observability at the end. Needs numpy (the CRLB) and a built `harrier`.

`--estimator tracker` scores the live service's estimator instead: the multi-target track engine
with its registrar (harrier-core's BiasBank), `harrier replay -e tracker --register` on the same
scenarios, its baselines the same engine on `told-bias` (nothing to register) and with
`--register` on `told-model`; its position error is that of the confirmed track nearest the truth
at each line (a line without a confirmed track is counted in `no track`).
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import registration_crlb  # noqa: E402

CASES = ["none", "constant", "gauss-markov", "mounting", "time-offset", "radar-reference",
         "radar-alone"]
# chi-square 95 % quantiles by degrees of freedom (scipy.stats.chi2.ppf(0.95, k)).
CHI2_95 = {1: 3.841459, 2: 5.991465, 3: 7.814728, 4: 9.487729, 5: 11.070498, 6: 12.591587}


def find_harrier(path):
    if path:
        return path
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for profile in ("release", "debug"):
        p = os.path.join(root, "target", profile, "harrier")
        if os.path.exists(p):
            return p
    raise SystemExit("no harrier binary: cargo build --release -p harrier-cli")


def seeds_of(text):
    if "-" in text:
        a, b = map(int, text.split("-"))
        return list(range(a, b + 1))
    return [int(s) for s in text.split(",")]


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}: {r.stderr.strip()}")
    return r.stdout


def generate(harrier, out, case, variant, seed, duration):
    d = os.path.join(out, f"{case}_{variant}_{seed}")
    run([harrier, "gen-registration", d, "--case", case, "--variant", variant, "--seed", str(seed),
         "--duration", str(duration)])
    return d


def replay(harrier, d, estimator, params=(), track_filter="ekf", register=False):
    est = os.path.join(d, f"estimates_{estimator}{'_reg' if register else ''}.jsonl")
    cmd = [harrier, "replay", d, "-e", estimator, "-o", est, "--json"]
    if estimator == "tracker":
        cmd += ["--track-filter", track_filter] + (["--register"] if register else [])
    for p in params:
        cmd += ["-p", p]
    run(cmd)
    with open(est) as f:
        return [json.loads(line) for line in f if line.strip()]


def truth_of(d):
    return registration_crlb.read_truth(os.path.join(d, "truth.csv"))


def pos_errors(estimates, truth, t_start):
    """Position errors from t_start on: of the line's `state`, or of a tracker's confirmed track
    nearest the truth; and the number of tracker lines without a confirmed track."""
    out, missing = [], 0
    for e in estimates:
        if e["t"] < t_start:
            continue
        pos, _ = registration_crlb.truth_at(truth, e["t"])
        states = [e["state"]] if e.get("state") is not None else \
            [k["state"] for k in e.get("tracks", [])]
        if not states:
            missing += "tracks" in e
            continue
        out.append(min(math.hypot(s[0] - pos[0], s[1] - pos[1]) for s in states))
    return np.array(out), missing


def rms(v):
    v = np.asarray(v, float)
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def bias_series(estimates, d, t_from):
    """Per (sensor, term): errors from t_from on and the error of the last line; per sensor: NEES
    per scan and the last line's `bias_est` entry."""
    table = registration_crlb.read_bias_truth(os.path.join(d, "bias_truth.csv"))
    errors, nees, last, final = {}, {}, {}, {}
    for e in estimates:
        for sensor, b in (e.get("bias_est") or {}).items():
            terms = b["terms"]
            err = np.array([_value(b, term) - registration_crlb.bias_value(table, sensor, term,
                                                                           e["t"])
                            for term in terms])
            last[sensor] = b
            for term, x in zip(terms, err):
                final[(sensor, term)] = float(x)
            if e["t"] < t_from:
                continue
            for term, x in zip(terms, err):
                errors.setdefault((sensor, term), []).append(x)
            cov = np.array(b["cov"])
            nees.setdefault(sensor, []).append(float(err @ np.linalg.solve(cov, err)))
    return errors, nees, last, final


def _value(b, term):
    if term == "time_offset":
        return b["time_offset"]
    key, i = ("offset", int(term[6:])) if term.startswith("offset") else ("scale", int(term[5:]))
    return b[key][i]


def observable(b, term):
    o = b["observable"]
    if term == "time_offset":
        return o.get("time_offset")
    key, i = ("offset", int(term[6:])) if term.startswith("offset") else ("scale", int(term[5:]))
    return o[key][i]


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="1-8")
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--harrier", default=None)
    ap.add_argument("--out", default=None)
    ap.add_argument("--from", dest="t_from", type=float, default=60.0)
    ap.add_argument("--param", action="append", default=[],
                    help="extra parameter NAME=VALUE of the estimator under test (repeatable)")
    ap.add_argument("--estimator", choices=["registration", "tracker"], default="registration",
                    help="registration: the replay estimator (default); tracker: the live "
                         "service's track engine with its registrar")
    ap.add_argument("--track-filter", default="ekf",
                    help="with --estimator tracker: the track filter (default ekf)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    harrier = find_harrier(a.harrier)
    out = a.out or tempfile.mkdtemp(prefix="harrier-registration-")
    seeds = seeds_of(a.seeds)
    cases = a.cases.split(",")
    result = {"seeds": seeds, "duration": a.duration, "from": a.t_from, "cases": {}}
    for case in cases:
        rows = {"rmse": {}, "bias": {}, "nees": {}, "observable": {}}
        sq = {}
        for seed in seeds:
            dep = generate(harrier, out, case, "deployment", seed, a.duration)
            truth = truth_of(dep)
            def under_test(d, params=(), register=True):
                return replay(harrier, d, a.estimator, params, a.track_filter, register)
            runs = {"registration": under_test(dep, a.param),
                    "ekf": replay(harrier, dep, "ekf")}
            told = generate(harrier, out, case, "told-bias", seed, a.duration)
            runs["told-bias"] = under_test(told, register=False)
            if case == "gauss-markov":
                model = generate(harrier, out, case, "told-model", seed, a.duration)
                runs["told-model"] = under_test(model)
            if case == "mounting":
                unbiased = generate(harrier, out, "none", "deployment", seed, a.duration)
                runs["unbiased run"] = under_test(unbiased, a.param)
            for name, est in runs.items():
                err, missing = pos_errors(est, truth, 10.0)
                rows["rmse"].setdefault(name, []).append(rms(err))
                rows.setdefault("no_track", {}).setdefault(name, []).append(missing)
            errors, nees, last, final = bias_series(runs["registration"], dep, a.t_from)
            bound = registration_crlb.crlb(dep, a.t_from)[0]["terms"]
            for b in bound:
                key = (b["sensor"], b["term"])
                e = errors.get(key, [])
                s = sq.setdefault(key, [0.0, 0.0, 0, 0, 0.0])
                s[0] += float(np.sum(np.square(e)))
                s[1] += (b["rms_after"] or 0.0) ** 2 * len(e)
                s[2] += len(e)
                s[3] += bool(observable(last[b["sensor"]], b["term"]))
                s[4] = max(s[4], abs(final.get(key, 0.0)))
            for sensor, v in nees.items():
                dof = len(last[sensor]["terms"])
                ok = np.mean(np.array(v) <= CHI2_95[dof])
                rows["nees"].setdefault(sensor, []).append(float(ok))
        for key, (e2, c2, n, obs, worst) in sq.items():
            if n == 0:
                continue
            rows["bias"][f"{key[0]}/{key[1]}"] = {
                "rms_error": math.sqrt(e2 / n), "rms_crlb": math.sqrt(c2 / n),
                "ratio": math.sqrt(e2 / c2) if c2 > 0 else float("nan"),
                "final_max_abs_error": worst,
                "observable_at_end": f"{obs}/{len(seeds)}"}
        result["cases"][case] = rows
    if a.json:
        print(json.dumps(result, indent=1))
        return
    print(f"{a.estimator}{'/' + a.track_filter if a.estimator == 'tracker' else ''}: "
          f"seeds {a.seeds}, {a.duration:.0f} s, bias figures from {a.t_from:.0f} s; data in {out}")
    for case, rows in result["cases"].items():
        print(f"\n## {case}")
        base = np.array(rows["rmse"]["told-bias"])
        for name, v in rows["rmse"].items():
            v = np.array(v)
            missing = sum(rows["no_track"][name])
            print(f"  pos RMSE {name:13} mean {v.mean():8.3f} m  max {v.max():8.3f}  "
                  f"ratio to told-bias mean {np.mean(v / base):.3f} max {np.max(v / base):.3f}"
                  + (f"  ({missing} lines without a track)" if missing else ""))
        reg = np.array(rows["rmse"]["registration"])
        for name in ("told-model", "unbiased run"):
            if name in rows["rmse"]:
                r = reg / np.array(rows["rmse"][name])
                print(f"  registration / {name}: mean {r.mean():.3f} max {r.max():.3f}")
        for k, b in rows["bias"].items():
            print(f"  bias {k:22} RMS err {b['rms_error']:.5g}  sqrt CRLB {b['rms_crlb']:.5g}  "
                  f"ratio {b['ratio']:.3f}  worst final |err| {b['final_max_abs_error']:.5g}  "
                  f"observable {b['observable_at_end']}")
        for sensor, v in rows["nees"].items():
            print(f"  bias NEES {sensor}: within chi2 95 % in {np.mean(v):.3f} of scans "
                  f"(worst seed {np.min(v):.3f})")


if __name__ == "__main__":
    main()
