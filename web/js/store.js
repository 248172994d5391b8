// What the page knows: tracks (with their histories), vehicles (with trails), recent detections,
// simulation truth, assignments and the stream's counters. Fed by WebSocket messages and REST
// polls; read by the map, the 3-D view and the panels. Times are the tracker's time line (s).

const HISTORY_LEN = 200;
const TRAIL_LEN = 300;
const DETECTION_TTL_S = 8; // wall-clock seconds a detection stays on screen (fading)
const TRUTH_LEN = 3000;
const SERIES_WINDOW_S = 180;
const STANDOFF_WINDOW_S = 300;

export class Store {
  constructor() {
    this.tracks = new Map(); // id → TrackState
    this.vehicles = new Map(); // label → VehicleState
    this.detections = []; // {at (performance.now ms), kind, vehicle, platform, z}
    this.truth = new Map(); // target id → {samples: [[t,x,y,z]], last: {t, position, velocity}}
    this.assignments = new Map(); // id → assignment body (AssignmentView)
    this.world = { roads: [], obstacles: [] }; // GET /world: the deployment's roads and obstacles
    this.aircraft = []; // GET /aircraft: manned aircraft of the ADS-B feed (never tracks)
    this.aircraftFeed = "off";
    this.standoff = new Map(); // assignment id → Map(vehicle label → {range: [[t, m]], spacing: [[t, deg]]})
    this.vehicleEvents = []; // the last vehicle events (vehicle_event messages), newest last
    this.estimator = null;
    this.biases = []; // GET /biases and the scans' `biases`: the registered sensors' bias estimates
    this.seq = 0;
    this.t = null;
    this.scans = 0; // scan messages received since the page loaded
    this.snapshots = 0;
    this.dropped = 0; // scan messages the server dropped for this page (lagging)
    this.gaps = 0; // seq gaps seen
    this.rates = []; // [performance.now ms, vehicle, detections] of recent scans
    this.planeZ = 0;
    this.version = 0; // bumped on every change (the panels redraw when it moves)
    this.onConfirmed = null; // callback(id) when a track is first seen confirmed
  }

  // --- WebSocket messages -------------------------------------------------------------------

  /** The registered sensors' bias estimates (`GET /biases`, or a scan's `biases`). */
  applyBiases(list) {
    this.biases = Array.isArray(list) ? list : [];
    this.version += 1;
  }

  /** `snapshot`: replaces the tracks and vehicles (a new server, or this page fell behind). */
  applySnapshot(msg) {
    this.snapshots += 1;
    this.dropped += msg.dropped || 0;
    this.seq = msg.seq || 0;
    this.t = msg.t ?? this.t;
    if (msg.estimator) this.estimator = msg.estimator;
    const seen = new Set();
    for (const k of msg.tracks || []) {
      seen.add(k.id);
      this.upsertTrack(k, false);
    }
    for (const id of [...this.tracks.keys()]) if (!seen.has(id)) this.tracks.delete(id);
    for (const v of msg.vehicles || []) this.upsertVehicle(v);
    this.version += 1;
  }

  /** `scan`: detections, events, changed tracks. */
  applyScan(msg) {
    if (msg.biases) this.applyBiases(msg.biases);
    if (this.seq && msg.seq > this.seq + 1) this.gaps += 1;
    this.seq = msg.seq;
    this.t = msg.t;
    this.scans += 1;
    const now = performance.now();
    const label = String(msg.vehicle);
    this.rates.push([now, label, (msg.detections || []).length]);
    for (const z of msg.detections || []) {
      this.detections.push({ at: now, kind: msg.kind, vehicle: label, platform: msg.platform, z });
    }
    // The platform pose from the scan: the vehicle's position even before /vehicles says so.
    if (msg.platform) {
      const v = this.vehicleFor(label);
      if (!v.linkPosition) this.moveVehicle(v, msg.platform, msg.t);
      v.lastScanT = msg.t;
      v.sensors.add(msg.sensor);
      v.scans += 1;
    }
    for (const k of msg.tracks || []) this.upsertTrack(k, true);
    for (const e of msg.events || []) {
      if (e.type === "deleted") this.tracks.delete(e.id);
    }
    this.version += 1;
  }

  /** `vehicles` or GET /vehicles; the stream's message also has the assignments. */
  applyVehicles(body) {
    for (const v of body.vehicles || []) this.upsertVehicle(v);
    if (Array.isArray(body.assignments)) this.applyAssignments(body.assignments);
    this.version += 1;
  }

  /** `vehicle_event`: connected, lost, recovered, mode, armed, disarmed. */
  applyVehicleEvent(e) {
    this.vehicleEvents.push({ ...e, at: Date.now() });
    if (this.vehicleEvents.length > 50) this.vehicleEvents.splice(0, this.vehicleEvents.length - 50);
    const v = this.vehicles.get(String(e.vehicle));
    if (v && v.link) {
      if (e.event === "lost") v.link = { ...v.link, state: "lost" };
      else if (e.event === "recovered" || e.event === "connected") v.link = { ...v.link, state: "connected" };
      if (e.mode) v.link = { ...v.link, mode: e.mode };
    }
    this.version += 1;
  }

  // --- tracks -------------------------------------------------------------------------------

  upsertTrack(view, fromScan) {
    let k = this.tracks.get(view.id);
    const isNew = !k;
    if (!k) {
      k = {
        id: view.id,
        view,
        history: [],
        ellipse: null,
        bound: null,
        firstSeen: view.t,
        series: [], // [t, value] (position error with truth, else ellipse major semi-axis)
        nees: null, // position NEES against the nearest true target (the server's, GET /truth)
        neesDim: null,
        error: null,
      };
      this.tracks.set(view.id, k);
    }
    k.view = view;
    k.ellipse = view.ellipse_95 || null; // {semi_axes: [a, b], angle_rad}, from the server
    const [x, y, z] = view.state;
    if (fromScan || isNew) {
      const h = k.history;
      if (!h.length || h[h.length - 1][0] < view.t) {
        if (view.updated || isNew) h.push([view.t, x, y, z]);
        if (h.length > HISTORY_LEN) h.splice(0, h.length - HISTORY_LEN);
      }
    }
    if (this.truth.size === 0 && k.ellipse) {
      if (k.seriesKind !== "sigma") k.series = [];
      k.seriesKind = "sigma";
      pushSeries(k.series, view.t, k.ellipse.semi_axes[0]);
    }
    if (view.status === "confirmed" && !k.confirmedSeen) {
      k.confirmedSeen = true;
      if (this.onConfirmed) this.onConfirmed(view.id);
    }
  }

  /** A track's history from GET /tracks/{id} (what happened before this page saw it). */
  mergeHistory(id, history, bound) {
    const k = this.tracks.get(id);
    if (!k) return;
    if (history && history.length) {
      const known = k.history.length ? k.history[0][0] : Infinity;
      const older = history.filter((p) => p[0] < known);
      k.history = older.concat(k.history).slice(-HISTORY_LEN);
    }
    if (bound !== undefined) k.bound = bound;
  }

  confirmed() {
    return [...this.tracks.values()].filter((k) => k.view.status === "confirmed");
  }

  // --- vehicles -----------------------------------------------------------------------------

  vehicleFor(label) {
    let v = this.vehicles.get(label);
    if (!v) {
      v = {
        label,
        position: null,
        velocity: null,
        heading: null, // rad, clockwise from North
        trail: [],
        sensors: new Set(),
        scans: 0,
        lastScanT: null,
        link: null,
        linkPosition: false,
      };
      this.vehicles.set(label, v);
    }
    return v;
  }

  moveVehicle(v, p, t) {
    const last = v.trail[v.trail.length - 1];
    if (!last || Math.hypot(p[0] - last[1], p[1] - last[2], p[2] - last[3]) > 0.5) {
      if (last && Math.hypot(p[0] - last[1], p[1] - last[2]) > 1.0 && !v.linkPosition) {
        v.heading = Math.atan2(p[0] - last[1], p[1] - last[2]);
      }
      // Without link telemetry, the velocity from the last two positions.
      const dt = last && t != null ? t - last[0] : 0;
      if (!v.linkPosition && dt > 0.05) v.velocity = [(p[0] - last[1]) / dt, (p[1] - last[2]) / dt, (p[2] - last[3]) / dt];
      v.trail.push([t ?? 0, p[0], p[1], p[2]]);
      if (v.trail.length > TRAIL_LEN) v.trail.splice(0, v.trail.length - TRAIL_LEN);
    } else if (!v.linkPosition && t != null && t - last[0] > 1) {
      v.velocity = [(p[0] - last[1]) / (t - last[0]), (p[1] - last[2]) / (t - last[0]), (p[2] - last[3]) / (t - last[0])];
    }
    v.position = p;
  }

  /** One vehicle, `{id, link: {...} | null, detections: {...} | null}` (the server's `VehicleEntry`). */
  upsertVehicle(raw) {
    const v = this.vehicleFor(String(raw.id));
    v.link = raw.link || null;
    v.clock = raw.clock || null;
    v.clockRefused = Number.isFinite(raw.clock_refused) ? raw.clock_refused : 0;
    const det = raw.detections || null;
    if (det) this.mergeDetectionView(v, det);
    if (v.link && Array.isArray(v.link.position)) {
      v.linkPosition = true;
      this.moveVehicle(v, v.link.position, det ? det.last_t : null);
      v.velocity = v.link.velocity || null;
      if (Number.isFinite(v.link.heading_deg)) v.heading = (v.link.heading_deg * Math.PI) / 180;
    } else {
      v.linkPosition = false;
    }
  }

  mergeDetectionView(v, det) {
    if (Array.isArray(det.sensors)) for (const s of det.sensors) v.sensors.add(s);
    if (Number.isFinite(det.scans)) v.scans = Math.max(v.scans, det.scans);
    if (Number.isFinite(det.last_t)) v.lastScanT = det.last_t;
    v.geodetic = det.geodetic || v.geodetic;
    if (!v.linkPosition && Array.isArray(det.position)) this.moveVehicle(v, det.position, det.last_t);
  }

  // --- truth, assignments, housekeeping ------------------------------------------------------

  applyTruth(body) {
    for (const s of body.targets || []) {
      let target = this.truth.get(s.id);
      if (!target) {
        target = { id: s.id, samples: [], last: null };
        this.truth.set(s.id, target);
      }
      const last = target.samples[target.samples.length - 1];
      if (!last || s.t > last[0]) {
        target.samples.push([s.t, s.position[0], s.position[1], s.position[2] ?? this.planeZ]);
        if (target.samples.length > TRUTH_LEN) target.samples.splice(0, target.samples.length - TRUTH_LEN);
      }
      target.last = s;
    }
    // Each track's error and NEES against the nearest target, as the server scored them.
    const scored = new Map((body.scores || []).map((s) => [s.track, s]));
    for (const k of this.tracks.values()) {
      const s = scored.get(k.id);
      k.error = s ? s.error_m : null;
      k.nees = s ? s.nees : null;
      k.neesDim = s ? s.dof : null;
      if (s) {
        if (k.seriesKind !== "error") k.series = [];
        k.seriesKind = "error";
        pushSeries(k.series, s.t, s.error_m);
      }
    }
    this.version += 1;
  }

  /** GET /world: roads (polylines) and obstacles (discs) of the server's configuration. */
  applyWorld(body) {
    this.world = { roads: body.roads || [], obstacles: body.obstacles || [] };
    this.version += 1;
  }

  /** GET /aircraft: the ADS-B aircraft, kept apart from the tracks. */
  applyAircraft(body) {
    this.aircraftFeed = body.feed || "off";
    this.aircraft = Array.isArray(body.aircraft) ? body.aircraft : [];
    this.version += 1;
  }

  /** The whole list (GET /assignments, the `vehicles` message). */
  applyAssignments(list) {
    this.assignments = new Map(list.map((a) => [a.id, a]));
    for (const a of list) this.scoreAssignment(a);
    for (const id of [...this.standoff.keys()]) if (!this.assignments.has(id)) this.standoff.delete(id);
    this.version += 1;
  }

  /** One assignment (the `assignment` message: created, a vehicle's state changed, ended). */
  applyAssignment(a) {
    this.assignments.set(a.id, a);
    this.scoreAssignment(a);
    this.version += 1;
  }

  /** The active assignment a vehicle flies, with its slot: {assignment, slot} or null. */
  slotOf(label) {
    for (const a of this.assignments.values()) {
      if (a.state !== "active") continue;
      const slot = (a.vehicles || []).find((x) => String(x.vehicle) === label);
      if (slot) return { assignment: a, slot };
    }
    return null;
  }

  /**
   * Standoff figures of an active assignment, per vehicle, against wall-clock time (s): the range
   * error r − R, and the spacing error: the phase gap from the vehicle before it on the ring (the
   * vehicles in orbit order, as the guidance orders them) minus the assignment's spacing. When the
   * vehicles do not fill the circle (n × spacing < 360°) the open gap is not an error.
   */
  scoreAssignment(a) {
    if (a.state !== "active") return;
    const t = Date.now() / 1000;
    let per = this.standoff.get(a.id);
    if (!per) {
      per = new Map();
      this.standoff.set(a.id, per);
    }
    const sign = a.orbit === "cw" ? -1 : 1;
    const flying = [];
    for (const slot of a.vehicles || []) {
      const label = String(slot.vehicle);
      let f = per.get(label);
      if (!f) {
        f = { range: [], spacing: [] };
        per.set(label, f);
      }
      if (slot.state !== "offboard") continue;
      if (Number.isFinite(slot.range_error_m)) pushSeries(f.range, t, slot.range_error_m, STANDOFF_WINDOW_S);
      if (Number.isFinite(slot.phase_deg)) flying.push({ f, phase: sign * slot.phase_deg });
    }
    const n = flying.length;
    if (n < 2) return;
    flying.sort((x, y) => x.phase - y.phase);
    const gaps = flying.map((x, k) => {
      const prev = flying[(k + n - 1) % n];
      return (((x.phase - prev.phase) % 360) + 360) % 360;
    });
    const open = n * a.spacing_deg < 359.5 ? gaps.indexOf(Math.max(...gaps)) : -1;
    flying.forEach((x, k) => {
      if (k !== open) pushSeries(x.f.spacing, t, gaps[k] - a.spacing_deg, STANDOFF_WINDOW_S);
    });
  }

  /** Forgets what is too old to draw; called once per frame. */
  prune(now) {
    const ttl = DETECTION_TTL_S * 1000;
    let i = 0;
    while (i < this.detections.length && now - this.detections[i].at > ttl) i++;
    if (i) this.detections.splice(0, i);
    if (this.detections.length > 4000) this.detections.splice(0, this.detections.length - 4000);
    let j = 0;
    while (j < this.rates.length && now - this.rates[j][0] > 5000) j++;
    if (j) this.rates.splice(0, j);
  }

  /** Scans/s and detections/s per vehicle over the last 5 s. */
  ingestRates() {
    const out = new Map();
    for (const [, label, n] of this.rates) {
      const r = out.get(label) || { scans: 0, detections: 0 };
      r.scans += 1 / 5;
      r.detections += n / 5;
      out.set(label, r);
    }
    return out;
  }

  /** Fraction (0–1) of a detection's life left. */
  static fade(d, now) {
    return Math.max(0, 1 - (now - d.at) / (DETECTION_TTL_S * 1000));
  }
}

function pushSeries(series, t, v, window = SERIES_WINDOW_S) {
  if (!Number.isFinite(v)) return;
  const last = series[series.length - 1];
  if (last && last[0] >= t) return;
  series.push([t, v]);
  while (series.length && t - series[0][0] > window) series.shift();
}

