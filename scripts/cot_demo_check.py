#!/usr/bin/env python3
"""Do TAK's own decoders read every CoT event of a `harrier demo`, where the API says? (issue 23)

    cargo build --release -p harrier-cli
    eval "$(scripts/setup --env)"
    scripts/cot_demo_check.py --bin target/release/harrier --seconds 300 --encoding both

For each encoding (xml, protobuf; `--encoding both` runs the two one after the other, or at
once with `--parallel`: the feed has one encoding per server): starts tests/python/cot_listen.py (UDP and TCP on loopback port 0,
every frame decoded with takproto, the TAK protocol library of pytak) and `harrier demo` (its API
on a free port, `--gcs udpin:127.0.0.1:0`, no router, `--record` into a temporary file: the
recording's session is where the REST API shows the frame origin) with `--cot` to both of the
listener's ports and `--cot-encoding`, and for `--seconds` of demo time records the tracker's
states two ways:

- the WebSocket `/api/v1/ws`: the snapshot, then every scan's `scan` message in order (the
  tracks the scan started, confirmed or updated, each with its `t`; `seq` shows none is lost);
- `GET /api/v1/tracks` polled at `--poll-hz`: the snapshot as it is, coasted tracks included
  (a scan also brings every track it does not update to its time, by prediction; the
  WebSocket does not send those states, but the CoT feed sends whatever the snapshot holds).

At the end every listener line must be a decoded event (0 error lines), and each event:
type `a-u-G`, how `m-f`, uid `harrier.harrier.track.<id>` and callsign `T<id>`, one uid per track
id; matched to the API's confirmed state of the same track at the event's `start` (the
estimate's time, ±2 ms, as tests/tests/it/field_cot.rs matches: takproto reads XML times
through a float) and its lat/lon/hae, converted into the demo's ENU frame (WGS-84, the API's
origin), within 0.5 m of it (the nearest, when several scans share that time). An event within
0.5 m of no state either record holds is explained from the WebSocket's scans at its `start`:
one of them coasted the track (a prediction the WebSocket does not carry) and no poll saw that
scan's snapshot (the cameras of several UAVs scan at the same time; the snapshot between two
such scans may live for milliseconds): allowed, counted and listed
(`unmatched_coasted`); any other is a failure. Prints a summary, then one JSON line (the
`summary` object, also written to `--json FILE`); exits 1 on a failure, 2 when it cannot run.

The demo's timestamps: CoT's `start` is the estimate's time, clamped to `time` (now, the wall
clock). With `--speedup` above 1 the simulator's clock runs ahead of the wall clock, `start` is
clamped and no longer the estimate's time: keep the default `--speedup 1` (5 minutes of demo
take 5 minutes).
"""

import argparse
import collections
import ctypes
import json
import math
import os
import platform
import queue
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

import httpx
from websockets.sync.client import connect as ws_connect

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LISTENER = os.path.join(ROOT, "tests", "python", "cot_listen.py")
TOLERANCE_M = 0.5
UID = re.compile(r"^harrier\.harrier\.track\.(\d+)$")

# WGS-84, as harrier-link's geo.rs.
A = 6378137.0
F = 1.0 / 298.257223563
E2 = F * (2.0 - F)


def ecef(lat_deg, lon_deg, alt_m):
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    n = A / math.sqrt(1.0 - E2 * math.sin(lat) ** 2)
    return (
        (n + alt_m) * math.cos(lat) * math.cos(lon),
        (n + alt_m) * math.cos(lat) * math.sin(lon),
        (n * (1.0 - E2) + alt_m) * math.sin(lat),
    )


class Frame:
    """The server's local ENU frame at a WGS-84 origin."""

    def __init__(self, lat_deg, lon_deg, alt_m):
        self.o = ecef(lat_deg, lon_deg, alt_m)
        sl, cl = math.sin(math.radians(lat_deg)), math.cos(math.radians(lat_deg))
        so, co = math.sin(math.radians(lon_deg)), math.cos(math.radians(lon_deg))
        self.r = ((-so, co, 0.0), (-sl * co, -sl * so, cl), (cl * co, cl * so, sl))

    def to_enu(self, lat_deg, lon_deg, alt_m):
        p = ecef(lat_deg, lon_deg, alt_m)
        d = [p[i] - self.o[i] for i in range(3)]
        return [sum(row[i] * d[i] for i in range(3)) for row in self.r]


try:
    _PRCTL = ctypes.CDLL(None, use_errno=True).prctl  # looked up here, not in the child
except (OSError, AttributeError):
    _PRCTL = None


def pdeathsig():
    """In the child: SIGKILL when the thread that started it ends (however this script ends)."""
    if _PRCTL is not None:
        _PRCTL(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG


def spawn(argv, stdout, stderr):
    """A child in a process group of its own, killed with this script."""
    return subprocess.Popen(
        argv,
        stdin=subprocess.DEVNULL,
        stdout=stdout,
        stderr=stderr,
        text=True,
        process_group=0,
        preexec_fn=pdeathsig,
    )


def stop_group(proc, sig=signal.SIGKILL, wait_s=10.0):
    """Sends `sig` to the child's process group, waits, then kills the group."""
    if proc is None or proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, sig)
        proc.wait(timeout=wait_s)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        pass
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


def lines_to_queue(stream, q):
    for line in iter(stream.readline, ""):
        q.put(line)
    q.put(None)


def next_line(q, timeout_s, what, pattern=None):
    """The next line (matching `pattern`) within `timeout_s`, or an error naming `what`."""
    deadline = time.monotonic() + timeout_s
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            raise RuntimeError(f"{what}: nothing within {timeout_s:.0f} s")
        try:
            line = q.get(timeout=left)
        except queue.Empty:
            raise RuntimeError(f"{what}: nothing within {timeout_s:.0f} s") from None
        if line is None:
            raise RuntimeError(f"{what}: the process ended")
        if pattern is None:
            return line
        m = re.search(pattern, line)
        if m:
            return m


class States:
    """The API's confirmed track states, by (track id, estimate time in ms): every distinct
    position seen there, and where it was seen."""

    def __init__(self):
        self.lock = threading.Lock()
        self.by_key = collections.defaultdict(dict)  # (id, ms) -> {(x, y, z): source}

    def add(self, tracks, source, seq):
        with self.lock:
            for k in tracks:
                if k.get("status") != "confirmed":
                    continue
                key = (k["id"], round(k["t"] * 1e3))
                pos = tuple(k["state"][:3])
                self.by_key[key].setdefault(pos, (source, set()))[1].add(seq)

    def near(self, track_id, start_ms):
        """[(position, source, the scan seqs it was seen after)] at start_ms ± 2 ms."""
        with self.lock:
            out = []
            for t in range(start_ms - 2, start_ms + 3):
                out += [(p, s, set(q)) for p, (s, q) in self.by_key.get((track_id, t), {}).items()]
            return out


def record_ws(url, states, scans, info, stop):
    """Every WebSocket message until the server closes it (or `stop`)."""
    try:
        with ws_connect(url, max_size=None, open_timeout=10) as ws:
            while not stop.is_set():
                try:
                    text = ws.recv(timeout=0.5)
                except TimeoutError:
                    continue
                m = json.loads(text)
                kind = m.get("type")
                if kind == "snapshot":
                    info["snapshots"] += 1
                    info["dropped"] += m.get("dropped", 0)
                    states.add(m.get("tracks", []), "ws", m.get("seq"))
                    info["last_seq"] = m.get("seq")
                elif kind == "scan":
                    if info["last_seq"] is not None and m["seq"] != info["last_seq"] + 1:
                        info["gaps"] += 1
                    info["last_seq"] = m["seq"]
                    states.add(m["tracks"], "ws", m["seq"])
                    scans.append(
                        (
                            round(m["t"] * 1e3),
                            m["seq"],
                            {e["id"]: e["type"] for e in m["events"] if "id" in e},
                        )
                    )
    except Exception as e:  # noqa: BLE001 - the server closing at the end ends it
        info["closed"] = repr(e)
    info["closed_at"] = time.monotonic()


def poll_rest(api, states, info, hz, stop):
    """GET /api/v1/tracks at `hz` until `stop`; the seqs it saw."""
    period = 1.0 / hz
    with httpx.Client(base_url=api, timeout=5.0) as c:
        while not stop.is_set():
            t0 = time.monotonic()
            try:
                body = c.get("/api/v1/tracks").json()
            except (httpx.HTTPError, ValueError):
                info["poll_errors"] += 1
            else:
                info["polls"] += 1
                info["seqs"].add(body["seq"])
                states.add(body["tracks"], "rest", body["seq"])
            stop.wait(max(0.0, period - (time.monotonic() - t0)))


def run(args, encoding):
    """One demo run with `encoding`: the figures and the failures."""
    failures = []
    tmp = tempfile.TemporaryDirectory(prefix="cot_demo_")
    listener = demo = None
    stop = threading.Event()
    threads = []
    try:
        listener = spawn(
            [sys.executable, LISTENER, "--timeout", str(args.seconds / args.speedup + 300)],
            subprocess.PIPE,
            subprocess.DEVNULL,
        )
        lq = queue.Queue()
        threading.Thread(target=lines_to_queue, args=(listener.stdout, lq), daemon=True).start()
        ready = json.loads(next_line(lq, 30, "cot_listen.py's ready line"))["ready"]
        dests = [f"udp://127.0.0.1:{ready['udp']}", f"tcp://127.0.0.1:{ready['tcp']}"]

        log = open(os.path.join(tmp.name, "demo.log"), "w")
        argv = [args.bin, "demo", "--listen", "127.0.0.1:0", "--gcs", "udpin:127.0.0.1:0"]
        argv += ["--router", "none", "--record", os.path.join(tmp.name, "session.sqlite")]
        argv += ["--speedup", str(args.speedup), "--seed", str(args.seed)]
        argv += ["--cot-encoding", encoding] + [a for d in dests for a in ("--cot", d)]
        demo = spawn(argv, subprocess.PIPE, log)
        dq = queue.Queue()
        threading.Thread(target=lines_to_queue, args=(demo.stdout, dq), daemon=True).start()
        m = next_line(dq, 120, "harrier demo's ready lines", r"dashboard\s+http://(\S+?)/\s*$")
        api = f"http://{m.group(1)}"
        started = time.monotonic()

        # The frame origin: the recording's session (GET /api/v1/sessions/{current}).
        with httpx.Client(base_url=api, timeout=5.0) as c:
            current = c.get("/api/v1/sessions").json()["current"]
            s = c.get(f"/api/v1/sessions/{current}").json()
        origin = (s["origin_lat_deg"], s["origin_lon_deg"], s["origin_alt_m"])
        frame = Frame(*origin)

        states, scans = States(), []
        ws_info = {"snapshots": 0, "dropped": 0, "gaps": 0, "last_seq": None, "closed": None}
        ws_info["closed_at"] = None
        rest_info = {"polls": 0, "poll_errors": 0, "seqs": set()}
        threads = [
            threading.Thread(
                target=record_ws,
                args=(f"ws://{m.group(1)}/api/v1/ws", states, scans, ws_info, stop),
                daemon=True,
            ),
            threading.Thread(
                target=poll_rest, args=(api, states, rest_info, args.poll_hz, stop), daemon=True
            ),
        ]
        for t in threads:
            t.start()

        # The listener's lines as they come, for the demo's time.
        lines, errors, other = [], [], []
        deadline = started + args.seconds / args.speedup

        def take(line):
            v = json.loads(line)
            if "error" in v:
                errors.append(v)
            elif "uid" in v:
                lines.append(v)
            else:
                other.append(v)

        while time.monotonic() < deadline:
            if demo.poll() is not None:
                raise RuntimeError(f"harrier demo ended early (exit {demo.returncode})")
            try:
                line = lq.get(timeout=min(1.0, max(0.01, deadline - time.monotonic())))
            except queue.Empty:
                continue
            if line is None:
                raise RuntimeError("cot_listen.py ended early")
            take(line)
        wall_s = time.monotonic() - started

        # Stop the demo first (Ctrl-C: it shuts down and closes the WebSocket), so that the
        # WebSocket and the poll hold every state an event can carry; then the listener.
        stopping = time.monotonic()
        stop_group(demo, signal.SIGINT, 20.0)
        threads[0].join(timeout=10)
        stop.set()
        threads[1].join(timeout=10)
        if (ws_info["closed_at"] or stopping) < stopping:
            failures.append(f"the WebSocket closed before the end: {ws_info['closed']}")
        stop_group(listener, signal.SIGTERM, 5.0)
        while True:
            try:
                line = lq.get(timeout=5)
            except queue.Empty:
                break
            if line is None:
                break
            take(line)
    finally:
        stop.set()
        stop_group(demo, signal.SIGINT, 20.0)
        stop_group(listener)
        tmp.cleanup()

    # The WebSocket's scans by time: which tracks each updated or coasted.
    scan_at = collections.defaultdict(list)
    for t_ms, seq, ev in scans:
        scan_at[t_ms].append((seq, ev))

    per_via = collections.Counter(e["via"] for e in lines)
    uid_of, ids_of = {}, collections.defaultdict(set)
    matched, ambiguous, worst, worst_event = 0, 0, 0.0, None
    by_source = collections.Counter()
    unmatched_coasted, unexplained, bad = [], [], []
    first_last = {}
    for e in lines:
        uid = e["uid"]
        m = UID.match(uid)
        if e["encoding"] != encoding:
            bad.append(f"encoding {e['encoding']}: {uid}")
        if not m:
            bad.append(f"uid {uid!r} is not harrier.harrier.track.<id>")
            continue
        tid = int(m.group(1))
        ids_of[uid].add(tid)
        uid_of.setdefault(tid, set()).add(uid)
        if (e["type"], e["how"], e["callsign"]) != ("a-u-G", "m-f", f"T{tid}"):
            bad.append(f"{uid}: type {e['type']} how {e['how']} callsign {e['callsign']}")
        start = e["start_ms"]
        fl = first_last.setdefault(uid, [start, start, 0])
        fl[0], fl[1], fl[2] = min(fl[0], start), max(fl[1], start), fl[2] + 1
        got = frame.to_enu(e["lat"], e["lon"], e["hae"])
        cands = states.near(tid, start)
        dist, src = min(((math.dist(got, p), s) for p, s, _ in cands), default=(None, None))
        if dist is not None and dist < TOLERANCE_M:
            matched += 1
            ambiguous += len(cands) > 1
            by_source[src] += 1
            if dist > worst:
                worst, worst_event = dist, {"uid": uid, "start_ms": start, "via": e["via"]}
            continue
        # No state seen within 0.5 m: which scans made a state of this track at this time, and
        # was each seen? A scan that coasted the track left a prediction the WebSocket does not
        # carry; unless a poll fell right after it, nobody saw it.
        seen_seqs = set().union(*(q for _, _, q in cands)) if cands else set()
        scans_then = [
            (seq, ev.get(tid), seq in seen_seqs)
            for t in range(start - 2, start + 3)
            for seq, ev in scan_at.get(t, [])
        ]
        what = {
            "uid": uid,
            "start_ms": start,
            "via": e["via"],
            "nearest_seen_m": dist,
            "scans": scans_then,
        }
        if any(kind == "coasted" and not was_seen for _, kind, was_seen in scans_then):
            unmatched_coasted.append(what)
        elif dist is not None:
            bad.append(f"{uid} at {start}: {dist:.3f} m from the API's state: {what}")
        else:
            unexplained.append(what)

    track_events = sum(1 for e in lines if UID.match(e["uid"]))
    stable = all(len(v) == 1 for v in uid_of.values()) and all(
        len(v) == 1 for v in ids_of.values()
    )
    if errors:
        failures.append(f"{len(errors)} listener lines takproto could not decode: {errors[:3]}")
    for via in ("udp", "tcp"):
        if per_via[via] == 0:
            failures.append(f"no event over {via}")
    if bad:
        failures.append(f"{len(bad)} bad events: {bad[:5]}")
    if not stable:
        failures.append(f"uids not one per track id: {uid_of}")
    if unexplained:
        failures.append(f"{len(unexplained)} events match no API state: {unexplained[:5]}")
    if ws_info["gaps"] or ws_info["dropped"]:
        failures.append(f"the WebSocket lost scans: {ws_info}")
    if track_events == 0:
        failures.append("no track event")
    span = (max(t for t, _, _ in scans) - min(t for t, _, _ in scans)) / 1e3 if scans else 0.0
    result = {
        "encoding": encoding,
        "events": len(lines),
        "by_transport": dict(sorted(per_via.items())),
        "track_events": track_events,
        "error_lines": len(errors),
        "matched": matched,
        "matched_by_source": dict(by_source),
        "matched_ambiguous": ambiguous,
        "matched_fraction": matched / track_events if track_events else 0.0,
        "unmatched_coasted": len(unmatched_coasted),
        "unmatched_coasted_examples": unmatched_coasted[:5],
        "unexplained": len(unexplained),
        "worst_m": worst,
        "worst_event": worst_event,
        "uids": {u: {"events": n, "first_ms": a, "last_ms": b} for u, (a, b, n) in
                 sorted(first_last.items())},
        "stable_uids": stable,
        "scans": len(scans),
        "scan_span_s": span,
        "wall_s": round(wall_s, 1),
        "polls": rest_info["polls"],
        "poll_errors": rest_info["poll_errors"],
        "scan_seqs_polled": len(rest_info["seqs"]),
        "ws": {k: ws_info[k] for k in ("snapshots", "dropped", "gaps")},
        "origin": origin,
        "tcp_connections": sum(1 for v in other if v.get("connected")),
        "failures": failures,
    }
    return result


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "harrier"))
    ap.add_argument("--seconds", type=float, default=300.0, help="demo time per encoding")
    ap.add_argument("--encoding", choices=["xml", "protobuf", "both"], default="both")
    ap.add_argument("--speedup", type=float, default=1.0, help="keep 1: see above")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--poll-hz", type=float, default=50.0, help="GET /api/v1/tracks rate")
    ap.add_argument(
        "--parallel",
        action="store_true",
        help="with --encoding both, run the two demos at once (half the wall time)",
    )
    ap.add_argument("--json", help="also write the summary to this file")
    args = ap.parse_args()
    if not os.path.isfile(args.bin):
        print(f"cot_demo_check: no {args.bin}: cargo build --release -p harrier-cli", file=sys.stderr)
        return 2
    # Ctrl-C or a kill ends the runs through their `finally` (children killed).
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(3))
    encodings = ["xml", "protobuf"] if args.encoding == "both" else [args.encoding]
    results, problems = {}, []

    def one(enc):
        try:
            results[enc] = run(args, enc)
        except Exception as e:  # noqa: BLE001 - reported, the exit code says it
            problems.append(f"{enc}: {e!r}")

    if args.parallel:
        workers = [threading.Thread(target=one, args=(enc,)) for enc in encodings]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
    else:
        for enc in encodings:
            one(enc)
    if problems:
        for p in problems:
            print(f"cot_demo_check: {p}", file=sys.stderr)
        return 2
    runs = [results[enc] for enc in encodings]
    summary = {
        "ok": all(not r["failures"] for r in runs),
        "seconds": args.seconds,
        "speedup": args.speedup,
        "poll_hz": args.poll_hz,
        "parallel": args.parallel,
        "machine": f"{cpu_model()}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}",
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "runs": runs,
    }
    for r in runs:
        print(
            f"{r['encoding']}: {r['events']} events {r['by_transport']} in {r['wall_s']} s "
            f"({r['scans']} scans over {r['scan_span_s']:.0f} s), {r['error_lines']} error "
            f"lines; {r['matched']}/{r['track_events']} matched "
            f"({100 * r['matched_fraction']:.2f} %, {r['matched_by_source']}), "
            f"{r['unmatched_coasted']} coasted states unseen by the poll, "
            f"{r['unexplained']} unexplained; worst {r['worst_m']:.4f} m; uids "
            f"{list(r['uids'])} stable {r['stable_uids']}",
            file=sys.stderr,
        )
        for f in r["failures"]:
            print(f"  FAIL {f}", file=sys.stderr)
    text = json.dumps(summary)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")
    print(text)
    return 0 if summary["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
