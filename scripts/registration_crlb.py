#!/usr/bin/env python3
"""Cramér–Rao bound of the sensor biases of a registration scenario (FORMAT-REGISTRATION.md).

    python3 scripts/registration_crlb.py DIR [--from 60] [--json] [--series]

Reads the scenario directory DIR (scenario.json with its sensors' bias blocks, measurements.jsonl,
references.jsonl if there, truth.csv, bias_truth.csv if there) and computes the posterior
Cramér–Rao bound (PCRLB) of the joint target + bias problem: the recursion of Tichavský,
Muravchik & Nehorai (IEEE Trans. SP 46(5), 1998) for the information J_k, for the model the scenario
states — the target's nearly-constant-velocity motion with white-noise acceleration
`motion.accel_std` from the scenario's Gaussian prior, and each bias term's dynamics (constant,
random walk or Gauss–Markov) from its prior (the `bias` blocks). Dynamics and noise are linear
and Gaussian, so the recursion J_{k+1} = D22 - D21 (J_k + D11)^-1 D12 is the Kalman covariance
recursion with every measurement Jacobian taken at the TRUE state (truth.csv, bias_truth.csv),
which this script runs in covariance form (P = J^-1; the form needs no inverse of a singular Q,
as a constant bias has). The measurements only give their times, sensors and platform poses.

A measurement of component i of a sensor is z_i = (1 + s_i) h_i(p(t - δ) - p_s) + o_i + v_i
(offset o, scale s, time offset δ); a reference (references.jsonl) is the same sensor's detection
of an object whose reported position has the covariance diag(std^2), which enters the noise as
R + G H_p Σ H_p^T G. Written independently of harrier-core's registration filter (numpy only).

Prints, per sensor and bias term, the square root of the bound at the end of the run and its RMS
over the scans from --from seconds on (the figure the acceptance compares the bias error with):
one JSON object with --json; --series adds every scan's bound.
"""
import argparse
import csv
import json
import math
import os

import numpy as np


def load_jsonl(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def term_names(block, dim):
    """The terms of a bias block in state order (offsets, scales, time offset) with their models."""
    out = []
    if not block:
        return out
    for key in ("offset", "scale"):
        for i, spec in enumerate(block.get(key) or []):
            if spec is not None:
                if i >= dim:
                    raise SystemExit(f"{key}[{i}] beyond the sensor's {dim} components")
                out.append((f"{key}{i}", spec))
    if block.get("time_offset") is not None:
        out.append(("time_offset", block["time_offset"]))
    return out


def transition(spec, dt):
    """(phi, process variance) of a bias term over dt (FORMAT-REGISTRATION.md section 1)."""
    model = spec["model"]
    if model == "constant":
        return 1.0, 0.0
    if model == "random_walk":
        return 1.0, spec["drift"] ** 2 * dt
    if model == "gauss_markov":
        phi = math.exp(-dt / spec["tau"])
        return phi, spec["std"] ** 2 * (1.0 - phi * phi)
    raise SystemExit(f"unknown bias model {model!r}")


def cv(q, dt):
    """Planar CV [x, y, vx, vy]: F and Q for white-noise acceleration of spectral density q."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt
    qm = np.zeros((4, 4))
    for a in range(2):
        qm[a, a] = dt ** 3 / 3
        qm[a, a + 2] = qm[a + 2, a] = dt ** 2 / 2
        qm[a + 2, a + 2] = dt
    return f, q * qm


def h_and_grad(kind, d):
    """Noise-free measurement of the relative position d (E, N, U) and its gradient d h / d d."""
    e, n, u = d
    hxy2 = e * e + n * n
    hxy = math.sqrt(hxy2)
    rho2 = hxy2 + u * u
    az = math.atan2(e, n)
    daz = np.array([n / hxy2, -e / hxy2, 0.0])
    if kind == "range_bearing":
        rho = math.sqrt(rho2)
        return np.array([rho, az]), np.vstack([d / rho, daz])
    if kind == "az_el":
        el = math.atan2(u, hxy)
        k = -u / (rho2 * hxy)
        return np.array([az, el]), np.vstack([daz, [k * e, k * n, hxy / rho2]])
    raise SystemExit(f"measurement kind {kind!r} is not supported here (range_bearing, az_el)")


def read_truth(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            rows.append([float(r[k]) for k in ("t", "x", "y", "z", "vx", "vy", "vz")])
    return np.array(rows)


def truth_at(truth, t):
    """Linear interpolation of truth.csv at t: position (3) and velocity (3)."""
    s = np.array([np.interp(t, truth[:, 0], truth[:, c]) for c in range(1, 7)])
    return s[:3], s[3:]


def read_bias_truth(path):
    table = {}
    if not os.path.exists(path):
        return table
    with open(path) as f:
        for r in csv.DictReader(f):
            table.setdefault((r["sensor"], r["term"]), []).append((float(r["t"]), float(r["value"])))
    return table


def bias_value(table, sensor, term, t):
    rows = table.get((sensor, term))
    if not rows:
        return 0.0
    value = rows[0][1]
    for rt, v in rows:
        if rt <= t + 1e-6:
            value = v
        else:
            break
    return value


def crlb(directory, t_from):
    sc = json.load(open(os.path.join(directory, "scenario.json")))
    if sc["dims"] != 2:
        raise SystemExit("planar scenarios only (dims = 2)")
    plane_z = sc.get("plane_z") or 0.0
    q = sc["motion"]["accel_std"] ** 2
    sensors = {}
    slots = []  # (sensor id, term name, spec)
    for s in sc["sensors"]:
        dim = len(s["noise"]["std"])
        terms = term_names(s.get("bias"), dim)
        index = {}
        for name, spec in terms:
            index[name] = 4 + len(slots)
            slots.append((s["id"], name, spec))
        sensors[s["id"]] = dict(kind=s["kind"], std=np.array(s["noise"]["std"]), dim=dim,
                                index=index)
    n = 4 + len(slots)
    prior = sc["prior"]
    dims = prior.get("cov_dims") or [0, 1, 3, 4]
    if dims != [0, 1, 3, 4]:
        raise SystemExit("the prior must cover [x, y, vx, vy] (cov_dims [0, 1, 3, 4])")
    p = np.zeros((n, n))
    p[:4, :4] = np.array(prior["cov"])
    for k, (_, _, spec) in enumerate(slots):
        p[4 + k, 4 + k] = spec["std"] ** 2
    truth = read_truth(os.path.join(directory, "truth.csv"))
    bias_truth = read_bias_truth(os.path.join(directory, "bias_truth.csv"))
    lines = [(m, None) for m in load_jsonl(os.path.join(directory, "measurements.jsonl"))]
    lines += [(r, r["object"]) for r in load_jsonl(os.path.join(directory, "references.jsonl"))]
    # References first at equal times, as the estimator takes them.
    lines.sort(key=lambda item: (item[0]["t"], item[1] is None))
    t = prior.get("t", 0.0)
    series = []
    for m, obj in lines:
        dt = m["t"] - t
        if dt > 0:
            f = np.eye(n)
            qq = np.zeros((n, n))
            f[:4, :4], qq[:4, :4] = cv(q, dt)
            for k, (_, _, spec) in enumerate(slots):
                f[4 + k, 4 + k], qq[4 + k, 4 + k] = transition(spec, dt)
            p = f @ p @ f.T + qq
            t = m["t"]
        s = sensors[m["sensor"]]
        ix = s["index"]
        value = {name: bias_value(bias_truth, m["sensor"], name, t) for name in ix}
        if obj is None:
            pos, vel = truth_at(truth, t)
            pos[2] = plane_z
        else:
            pos, vel = np.array(obj["pos"], float), np.array(obj["vel"], float)
        delta = value.get("time_offset", 0.0)
        vrel = vel - np.array(m["platform"]["vel"], float)
        d = pos - delta * vrel - np.array(m["platform"]["pos"], float)
        h, hp = h_and_grad(s["kind"], d)
        g = np.array([1.0 + value.get(f"scale{i}", 0.0) for i in range(s["dim"])])
        ghp = g[:, None] * hp
        jac = np.zeros((s["dim"], n))
        if obj is None:
            jac[:, 0:2] = ghp[:, 0:2]
            jac[:, 2:4] = -delta * ghp[:, 0:2]
        for i in range(s["dim"]):
            if f"offset{i}" in ix:
                jac[i, ix[f"offset{i}"]] = 1.0
            if f"scale{i}" in ix:
                jac[i, ix[f"scale{i}"]] = h[i]
        if "time_offset" in ix:
            jac[:, ix["time_offset"]] = -ghp @ vrel
        r = np.diag(s["std"] ** 2)
        if obj is not None:
            r = r + ghp @ np.diag(np.array(obj["std"], float) ** 2) @ ghp.T
        # Covariance form of the PCRLB update: J <- J + H^T R^-1 H, as P <- (I - K H) P.
        sm = jac @ p @ jac.T + r
        k = np.linalg.solve(sm, jac @ p).T
        ikh = np.eye(n) - k @ jac
        p = ikh @ p @ ikh.T + k @ r @ k.T
        p = 0.5 * (p + p.T)
        if obj is None and (not series or series[-1][0] != t):
            series.append((t, np.sqrt(np.maximum(np.diag(p)[4:], 0.0))))
        elif obj is None:
            series[-1] = (t, np.sqrt(np.maximum(np.diag(p)[4:], 0.0)))
    out = {"scenario": sc["name"], "from": t_from, "terms": []}
    after = np.array([sd for (tt, sd) in series if tt >= t_from])
    for k, (sensor, name, spec) in enumerate(slots):
        entry = {"sensor": sensor, "term": name, "prior_std": spec["std"],
                 "end": float(series[-1][1][k]) if series else None,
                 "rms_after": float(np.sqrt(np.mean(after[:, k] ** 2))) if len(after) else None}
        out["terms"].append(entry)
    return out, series, slots


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir")
    ap.add_argument("--from", dest="t_from", type=float, default=60.0,
                    help="RMS of the bound over the scans from this time on (s, default 60)")
    ap.add_argument("--json", action="store_true", help="one JSON object on stdout")
    ap.add_argument("--series", action="store_true", help="with --json: every scan's bound")
    a = ap.parse_args()
    out, series, slots = crlb(a.dir, a.t_from)
    if a.series:
        out["series"] = {"t": [t for t, _ in series],
                         "std": [[float(v) for v in sd] for _, sd in series],
                         "terms": [f"{s}/{n}" for s, n, _ in slots]}
    if a.json:
        print(json.dumps(out))
        return
    print(f"{out['scenario']}: sqrt(PCRLB) of each bias term (prior std, end, RMS from {a.t_from} s)")
    for e in out["terms"]:
        print(f"  {e['sensor']:8} {e['term']:12} prior {e['prior_std']:.6g}  end {e['end']:.6g}  "
              f"rms {e['rms_after']:.6g}")


if __name__ == "__main__":
    main()
