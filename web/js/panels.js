// The side panels: vehicles (with commands), tracks, assignments, estimator, time series and
// service counters. DOM nodes are keyed and updated in place (inputs keep their focus and value).

import { colorFor, cssSize, fmt, fmtDist } from "./util.js";

/** `el("div", {class: "x"}, child…)`. */
export function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v == null || v === false) continue;
    if (k === "class") e.className = v;
    else if (k === "text") e.textContent = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else if (k === "style") e.style.cssText = v;
    else e.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children) if (c != null) e.append(c);
  return e;
}

/** Sets a node's text only when it differs (no DOM mutation, no relayout, when unchanged). */
export function setText(node, text) {
  if (node.textContent !== text) node.textContent = text;
}

/** Shows an action's outcome in `node`: "pending", "ok" or "bad". */
export function showResult(node, kind, text) {
  node.className = `result ${kind}`;
  node.textContent = text;
  node.dataset.state = kind;
}

/** A list longer than this updates only the cards on screen (a swarm's 255 vehicle cards). */
const EVERY_CARD_UP_TO = 24;

/**
 * Which cards of a panel are on screen (an IntersectionObserver): in a long list only those are
 * refreshed, each other card once when it is made and again when it scrolls into view.
 */
class OnScreen {
  constructor() {
    this.shown = new Set();
    this.observer =
      typeof IntersectionObserver === "function"
        ? new IntersectionObserver((entries) => {
            for (const e of entries) {
              if (e.isIntersecting) this.shown.add(e.target);
              else this.shown.delete(e.target);
            }
          })
        : null;
  }

  watch(node) {
    this.observer?.observe(node);
  }

  forget(node) {
    this.observer?.unobserve(node);
    this.shown.delete(node);
  }

  /** Whether card `c` (`{node, filled}`) of a list of `n` is to be refreshed now. */
  due(c, n) {
    if (!this.observer || n <= EVERY_CARD_UP_TO || !c.filled) {
      c.filled = true;
      return true;
    }
    return this.shown.has(c.node);
  }
}

// --- vehicles --------------------------------------------------------------------------------

/** A clock offset: ms below a second, s above. */
function fmtOffset(s) {
  return Math.abs(s) < 1 ? `${fmt(s * 1000, 0)} ms` : `${fmt(s, 3)} s`;
}

export class VehiclesPanel {
  constructor(root, store, actions) {
    this.root = root;
    this.store = store;
    this.actions = actions; // {command(label, command, altitude, resultNode)} or null
    this.cards = new Map();
    this.onScreen = new OnScreen();
    this.count = document.getElementById("vehicles-count");
  }

  card(v) {
    let c = this.cards.get(v.label);
    if (c) return c;
    const f = {};
    const cell = (name) => (f[name] = el("span", { class: "v" }));
    const grid = el(
      "div",
      { class: "grid" },
      el("span", { class: "k", text: "alt" }), cell("alt"),
      el("span", { class: "k", text: "battery" }), cell("battery"),
      el("span", { class: "k", text: "speed" }), cell("speed"),
      el("span", { class: "k", text: "link" }), cell("rate"),
      el("span", { class: "k", text: "scans" }), cell("scans"),
      el("span", { class: "k", text: "last seen" }), cell("seen"),
      el("span", { class: "k", text: "clock" }), cell("clock"),
    );
    f.title = el("span", { class: "title" });
    f.mode = el("span", { class: "tag" });
    f.armed = el("span", { class: "tag" });
    f.link = el("span", { class: "tag" });
    f.warn = el("div", { class: "warnline", hidden: true });
    f.assigned = el("div", { class: "assigned" });
    f.sensors = el("div", { class: "note" });
    const node = el("div", { class: "card", "data-vehicle": v.label },
      el("div", { class: "head" }, f.title, f.mode, f.armed, el("span", { class: "spacer" }), f.link),
      grid, f.warn, f.assigned, f.sensors);
    if (this.actions) {
      f.result = el("span", { class: "result" });
      f.takeoffAlt = el("input", { type: "number", value: "30", min: "1", step: "any", title: "takeoff altitude (m)" });
      const btn = (label, command) =>
        el("button", {
          type: "button",
          "data-command": command,
          text: label,
          onclick: () => this.actions.command(v.label, command, Number(f.takeoffAlt.value), f.result),
        });
      node.append(
        el("div", { class: "actions" }, btn("Arm", "arm"), btn("Takeoff", "takeoff"), f.takeoffAlt,
          btn("Hold", "hold"), btn("Land", "land"), btn("Disarm", "disarm")),
        el("div", {}, f.result),
      );
    }
    c = { node, f };
    this.cards.set(v.label, c);
    this.onScreen.watch(node);
    return c;
  }

  update() {
    const s = this.store;
    const list = [...s.vehicles.values()].sort((a, b) => a.label.localeCompare(b.label, undefined, { numeric: true }));
    if (!list.length) return;
    const empty = this.root.querySelector(".empty");
    if (empty) empty.remove();
    setText(this.count, `${list.length}`);
    for (const v of list) {
      const c = this.card(v);
      const { node, f } = c;
      if (!node.isConnected) this.root.append(node);
      if (!this.onScreen.due(c, list.length)) continue;
      const link = v.link;
      const alt = v.position ? v.position[2] - s.planeZ : NaN;
      setText(f.title, `UAV ${v.label}`);
      setText(f.alt, `${fmt(alt, 0)} m`);
      const vel = v.velocity;
      setText(f.speed, vel ? `${fmt(Math.hypot(vel[0], vel[1]), 1)} m/s` : "–");
      setText(f.scans, `${v.scans}`);
      setText(f.seen, link && Number.isFinite(link.last_seen_s) ? `${fmt(link.last_seen_s, 1)} s` : s.t != null && v.lastScanT != null ? `${fmt(Math.max(0, s.t - v.lastScanT), 1)} s` : "–");
      setText(f.sensors, v.sensors.size ? `sensors: ${[...v.sensors].join(", ")}` : "");
      // The vehicle's clock minus the server's (estimated from its scans), and its refused scans.
      const ck = v.clock;
      setText(f.clock, ck
        ? `${ck.offset_s >= 0 ? "+" : ""}${fmtOffset(ck.offset_s)} ±${fmtOffset(ck.sigma_s)}${v.clockRefused ? ` · ${v.clockRefused} refused` : ""}`
        : "–");
      f.clock.classList.toggle("bad", Boolean(v.clockRefused));
      const slot = s.slotOf(v.label);
      setText(f.assigned, slot
        ? `assignment #${slot.assignment.id} → T${slot.assignment.track}: ${slot.slot.state.replace("_", " ")}${Number.isFinite(slot.slot.range_error_m) ? ` · r−R ${fmt(slot.slot.range_error_m, 1)} m` : ""}`
        : "");
      if (link) {
        setText(f.mode, link.mode || "mode ?");
        f.mode.hidden = false;
        setText(f.armed, link.armed ? "ARMED" : "disarmed");
        f.armed.className = `tag ${link.armed ? "warn" : ""}`;
        f.armed.hidden = false;
        const lost = link.state === "lost";
        setText(f.link, lost ? "LINK LOST" : "link ok");
        f.link.className = `tag ${lost ? "bad" : "ok"}`;
        setText(f.battery, Number.isFinite(link.battery_pct) ? `${fmt(link.battery_pct, 0)} %` : "–");
        setText(f.rate, Number.isFinite(link.rate_hz)
          ? `${fmt(link.rate_hz, 0)} Hz${Number.isFinite(link.loss_pct) ? ` ${fmt(link.loss_pct, 0)}% loss` : ""}`
          : "–");
        f.warn.hidden = !lost;
        setText(f.warn, lost ? `Lost link: nothing heard for ${fmt(link.last_seen_s, 1)} s` : "");
        node.classList.toggle("lost", lost);
        node.dataset.link = link.state;
      } else {
        f.mode.hidden = true;
        f.armed.hidden = true;
        setText(f.link, "detections only");
        f.link.className = "tag";
        setText(f.battery, "–");
        setText(f.rate, "–");
        f.warn.hidden = true;
        node.dataset.link = "none";
      }
    }
  }
}

// --- tracks ----------------------------------------------------------------------------------

export class TracksPanel {
  constructor(root, store, onFollow) {
    this.root = root;
    this.store = store;
    this.onFollow = onFollow;
    this.cards = new Map();
    this.onScreen = new OnScreen();
    this.count = document.getElementById("tracks-count");
  }

  card(k) {
    let c = this.cards.get(k.id);
    if (c) return c;
    const f = {};
    const cell = (name) => (f[name] = el("span", { class: "v" }));
    f.title = el("span", { class: "title" });
    f.est = el("span", { class: "tag" });
    f.follow = el("button", { type: "button", text: "Follow", onclick: () => this.onFollow(k.id) });
    f.bars = el("div", { class: "bars" });
    const node = el("div", { class: "card", "data-track": k.id, style: `--card-color: ${colorFor(k.id)}` },
      el("div", { class: "head" }, f.title, f.est, el("span", { class: "spacer" }), f.follow),
      el("div", { class: "grid" },
        el("span", { class: "k", text: "speed" }), cell("speed"),
        el("span", { class: "k", text: "age" }), cell("age"),
        el("span", { class: "k", text: "95% a×b" }), cell("ell"),
        el("span", { class: "k", text: "since upd" }), cell("upd"),
        el("span", { class: "k", text: "E, N" }), cell("pos"),
        el("span", { class: "k", text: "NEES" }), cell("nees"),
        el("span", { class: "k", text: "error" }), cell("err"),
        el("span", { class: "k", text: "OBE" }), cell("bound"),
        el("span", { class: "k", text: "exists" }), cell("exist"),
      ),
      f.bars);
    c = { node, f, modes: -1 };
    this.cards.set(k.id, c);
    this.onScreen.watch(node);
    return c;
  }

  update(follow) {
    const s = this.store;
    const list = s.confirmed().sort((a, b) => a.id - b.id);
    setText(this.count, `${list.length} confirmed, ${s.tracks.size - list.length} tentative`);
    const ids = new Set(list.map((k) => k.id));
    for (const [id, c] of this.cards) {
      if (!ids.has(id)) {
        c.node.remove();
        this.onScreen.forget(c.node);
        this.cards.delete(id);
      }
    }
    const empty = this.root.querySelector(".empty");
    if (list.length && empty) empty.remove();
    if (!list.length && !empty) this.root.append(el("p", { class: "empty", text: "No confirmed track yet." }));
    let prev = null;
    for (const k of list) {
      const c = this.card(k);
      const { node, f } = c;
      // Keep id order without moving nodes that are already in place.
      if (prev ? prev.nextSibling !== node : this.root.firstChild !== node) {
        if (prev) prev.after(node);
        else this.root.prepend(node);
      }
      prev = node;
      if (!this.onScreen.due(c, list.length)) continue;
      const v = k.view;
      setText(f.title, `T${k.id}`);
      f.title.style.color = colorFor(k.id);
      setText(f.est, s.estimator ? s.estimator.name : "");
      setText(f.speed, `${fmt(Math.hypot(v.state[3], v.state[4]), 1)} m/s`);
      const since = k.history.length ? k.history[0][0] : k.firstSeen;
      setText(f.age, `${v.age} scans · ${fmt(v.t - since, 0)} s`);
      f.age.title = "scans since initiation · time since the oldest position of its history";
      setText(f.ell, k.ellipse ? `${fmt(k.ellipse.semi_axes[0], 1)}×${fmt(k.ellipse.semi_axes[1], 1)}` : "–");
      setText(f.upd, s.t != null ? `${fmt(Math.max(0, s.t - v.last_update), 1)} s` : "–");
      setText(f.pos, `${fmt(v.state[0], 0)}, ${fmt(v.state[1], 0)}`);
      setText(f.nees, k.nees != null && Number.isFinite(k.nees) ? fmt(k.nees, 2) : "–");
      f.nees.title = k.nees != null ? `position NEES (${k.neesDim} dof; 95 % bound ${k.neesDim === 3 ? "7.81" : "5.99"})` : "needs simulation truth";
      setText(f.err, k.error != null ? `${fmt(k.error, 1)} m` : "–");
      setText(f.exist, v.existence != null ? `${(100 * v.existence).toFixed(v.existence > 0.999 ? 2 : 1)}%` : "–");
      f.exist.title = v.existence != null ? "probability that the track follows a real target (jipda, mht)" : "no existence under the gnn associator";
      setText(f.bound, k.bound ? `${fmt(k.bound.semi_axes[0], 0)}×${fmt(k.bound.semi_axes[1], 0)}` : "–");
      setText(f.follow, follow === k.id ? "Following" : "Follow");
      f.follow.classList.toggle("on", follow === k.id);
      const probs = v.mode_probabilities || [];
      if (c.modes !== probs.length) {
        f.bars.replaceChildren(
          ...probs.map((_, i) =>
            el("div", { class: "bar" }, el("span", { text: `mode ${i + 1}` }),
              el("span", { class: "track" }, el("span", { class: "fill" })), el("span", { class: "pct" }))),
        );
        c.modes = probs.length;
      }
      probs.forEach((p, i) => {
        const bar = f.bars.children[i];
        const w = `${(100 * p).toFixed(0)}%`;
        const fill = bar.querySelector(".fill");
        if (fill.style.width !== w) fill.style.width = w;
        setText(bar.querySelector(".pct"), `${(100 * p).toFixed(0)}%`);
      });
    }
  }
}

// --- time series -----------------------------------------------------------------------------

export class SeriesPanel {
  constructor(canvas, store) {
    this.canvas = canvas;
    this.store = store;
    this.title = document.getElementById("series-title");
    this.note = document.getElementById("series-note");
  }

  update() {
    const s = this.store;
    const plot = clearedCanvas(this.canvas);
    if (!plot) return;
    const { ctx, w, h } = plot;
    const truth = s.truth.size > 0;
    setText(this.title, truth ? "Position error vs time" : "95 % ellipse semi-major axis vs time");
    setText(
      this.note,
      truth
        ? "Distance from each track to the nearest true target (simulation)."
        : "No simulation truth from this server: the estimates' own 95 % uncertainty instead of their error.",
    );
    const series = s.confirmed().filter((k) => k.series.length > 1);
    const t1 = s.t ?? 0;
    const t0 = t1 - 120;
    let ymax = 1;
    for (const k of series) for (const [t, v] of k.series) if (t >= t0) ymax = Math.max(ymax, v);
    ymax *= 1.1;
    const L = 40;
    const B = 18;
    const pw = w - L - 6;
    const ph = h - B - 6;
    ctx.font = "10px ui-monospace, Menlo, monospace";
    ctx.strokeStyle = "#1f2d3b";
    ctx.fillStyle = "#7f90a2";
    ctx.lineWidth = 1;
    const ystep = niceTick(ymax / 4);
    for (let y = 0; y <= ymax; y += ystep) {
      const py = 6 + ph - (y / ymax) * ph;
      ctx.beginPath();
      ctx.moveTo(L, Math.round(py) + 0.5);
      ctx.lineTo(L + pw, Math.round(py) + 0.5);
      ctx.stroke();
      ctx.fillText(fmtDist(y).replace(" ", ""), 2, py + 3);
    }
    for (let dt = 0; dt <= 120; dt += 30) {
      const px = L + (1 - dt / 120) * pw;
      ctx.fillText(dt ? `-${dt}s` : "now", px - (dt ? 12 : 20), h - 4);
    }
    for (const k of series) {
      ctx.strokeStyle = colorFor(k.id);
      ctx.lineWidth = 1.4;
      ctx.beginPath();
      let started = false;
      for (const [t, v] of k.series) {
        if (t < t0) continue;
        const px = L + ((t - t0) / 120) * pw;
        const py = 6 + ph - (v / ymax) * ph;
        if (started) ctx.lineTo(px, py);
        else ctx.moveTo(px, py);
        started = true;
      }
      ctx.stroke();
    }
    if (!series.length) {
      ctx.fillStyle = "#5f6f80";
      ctx.font = "12px system-ui, sans-serif";
      ctx.fillText("waiting for confirmed tracks…", L + 10, 6 + ph / 2);
    }
  }
}

// --- standoff: range and spacing errors of the assignments --------------------------------------

const STANDOFF_SPAN_S = 120;

/** Lines [{color, label, points: [[t, v]]}] over the last `span` s to `now`, y symmetric around 0. */
/**
 * The 2-D context of canvas `c`, its backing store sized to its CSS size × the device pixel
 * ratio, scaled to CSS pixels and cleared; null while it has no size (hidden).
 */
function clearedCanvas(c) {
  const dpr = window.devicePixelRatio || 1;
  const [w, h] = cssSize(c);
  if (!w || !h) return null;
  if (c.width !== Math.round(w * dpr)) c.width = Math.round(w * dpr);
  if (c.height !== Math.round(h * dpr)) c.height = Math.round(h * dpr);
  const ctx = c.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.clearRect(0, 0, w, h);
  return { ctx, w, h };
}

function plotLines(c, lines, now, unit, span = STANDOFF_SPAN_S) {
  const plot = clearedCanvas(c);
  if (!plot) return;
  const { ctx, w, h } = plot;
  const t0 = now - span;
  let ymax = 1;
  for (const l of lines) for (const [t, v] of l.points) if (t >= t0) ymax = Math.max(ymax, Math.abs(v));
  ymax = niceTick(ymax * 1.15) * Math.ceil((ymax * 1.15) / niceTick(ymax * 1.15));
  const L = 40;
  const B = 16;
  const pw = w - L - 6;
  const ph = h - B - 6;
  const yOf = (v) => 6 + ph / 2 - (v / ymax) * (ph / 2);
  ctx.font = "10px ui-monospace, Menlo, monospace";
  ctx.lineWidth = 1;
  ctx.fillStyle = "#7f90a2";
  for (const y of [-ymax, -ymax / 2, 0, ymax / 2, ymax]) {
    const py = Math.round(yOf(y)) + 0.5;
    ctx.strokeStyle = y === 0 ? "#3a5066" : "#1f2d3b";
    ctx.beginPath();
    ctx.moveTo(L, py);
    ctx.lineTo(L + pw, py);
    ctx.stroke();
    ctx.fillText(`${fmt(y, Math.abs(ymax) < 10 ? 1 : 0)}${unit}`, 2, py + 3);
  }
  for (let dt = 0; dt <= span; dt += 30) {
    const px = L + (1 - dt / span) * pw;
    ctx.fillText(dt ? `-${dt}s` : "now", px - (dt ? 12 : 20), h - 3);
  }
  let drawn = 0;
  for (const l of lines) {
    ctx.strokeStyle = l.color;
    ctx.lineWidth = 1.4;
    ctx.beginPath();
    let started = false;
    for (const [t, v] of l.points) {
      if (t < t0) continue;
      const px = L + ((t - t0) / span) * pw;
      const py = yOf(Math.max(-ymax, Math.min(ymax, v)));
      if (started) ctx.lineTo(px, py);
      else ctx.moveTo(px, py);
      started = true;
    }
    if (started) {
      ctx.stroke();
      drawn += 1;
    }
  }
  // Legend.
  let x = L + 6;
  ctx.font = "10.5px system-ui, sans-serif";
  for (const l of lines) {
    ctx.fillStyle = l.color;
    ctx.fillRect(x, 9, 10, 3);
    ctx.fillText(l.label, x + 13, 14);
    x += ctx.measureText(l.label).width + 24;
  }
  return drawn;
}

const UAV_COLORS = ["#7fd4ff", "#ffb86b", "#b99cff", "#7dff9b", "#ff7fb0", "#ffe36b", "#6bfff2", "#ff8c6b"];
export const uavColor = (label) => UAV_COLORS[(Number(label) || [...String(label)].reduce((a, c) => a + c.charCodeAt(0), 0)) % UAV_COLORS.length];

/** The range error r − R and the spacing error of each vehicle of the newest active assignment. */
export class StandoffPanel {
  constructor(rangeCanvas, spacingCanvas, store) {
    this.range = rangeCanvas;
    this.spacing = spacingCanvas;
    this.store = store;
    this.title = document.getElementById("standoff-title");
    this.note = document.getElementById("standoff-note");
    this.stats = { assignment: null, rangeLines: 0, spacingLines: 0, rms: null };
  }

  update() {
    const s = this.store;
    const active = [...s.assignments.values()].filter((a) => a.state === "active").sort((a, b) => b.id - a.id);
    const a = active[0] || [...s.assignments.values()].sort((x, y) => y.id - x.id)[0];
    const per = a ? s.standoff.get(a.id) : null;
    const now = Date.now() / 1000;
    const lines = (key) =>
      per ? [...per].map(([label, f]) => ({ color: uavColor(label), label: `UAV ${label}`, points: f[key] })) : [];
    const rl = lines("range");
    const sl = lines("spacing");
    this.stats.assignment = a ? a.id : null;
    this.stats.rangeLines = plotLines(this.range, rl, now, "m") || 0;
    this.stats.spacingLines = plotLines(this.spacing, sl, now, "°") || 0;
    // RMS of the range error over the plotted window.
    const recent = rl.flatMap((l) => l.points.filter(([t]) => t >= now - STANDOFF_SPAN_S).map(([, v]) => v));
    this.stats.rms = recent.length ? Math.sqrt(recent.reduce((acc, v) => acc + v * v, 0) / recent.length) : null;
    setText(this.title, a ? `#${a.id} → T${a.track} · ${a.law} R ${fmt(a.radius_m, 0)} m${a.state === "active" ? "" : " · ended"}` : "");
    setText(
      this.note,
      !a
        ? "No assignment: assign vehicles to a track to see their standoff errors."
        : this.stats.rms != null
          ? `r − R RMS ${fmt(this.stats.rms, 1)} m over ${fmt(Math.min(STANDOFF_SPAN_S, now - Math.min(...rl.flatMap((l) => l.points.map((p) => p[0])))), 0)} s (vehicles in OFFBOARD: climbing, joining, orbiting).`
          : "Waiting for the vehicles to fly it (OFFBOARD).",
    );
  }
}

function niceTick(x) {
  const e = Math.pow(10, Math.floor(Math.log10(Math.max(x, 1e-9))));
  const f = x / e;
  return (f > 5 ? 10 : f > 2 ? 5 : f > 1 ? 2 : 1) * e;
}

// --- service ---------------------------------------------------------------------------------

/** Parses the Prometheus text format into [{name, labels, value}]. */
export function parseMetrics(text) {
  const out = [];
  for (const line of text.split("\n")) {
    if (!line || line.startsWith("#")) continue;
    const m = line.match(/^([a-zA-Z_:][\w:]*)(\{([^}]*)\})?\s+(\S+)/);
    if (!m) continue;
    const labels = {};
    if (m[3]) for (const kv of m[3].matchAll(/(\w+)="([^"]*)"/g)) labels[kv[1]] = kv[2];
    out.push({ name: m[1], labels, value: Number(m[4]) });
  }
  return out;
}

export class ServicePanel {
  constructor(table, store, stream) {
    this.table = table;
    this.store = store;
    this.stream = stream;
    this.metrics = null;
    this.metricsError = null;
  }

  update() {
    const s = this.store;
    const rows = [];
    const row = (k, v, bad = false) => rows.push([k, v, bad]);
    const st = this.stream;
    row("stream", st.state, st.state !== "open");
    row("reconnections", `${st.reconnects}`);
    row("messages received", `${st.messages}`);
    row("last message", st.lastMessageAt ? `${fmt((performance.now() - st.lastMessageAt) / 1000, 1)} s ago` : "–");
    row("seq gaps · dropped to snapshot", `${s.gaps} · ${s.dropped}`, s.dropped > 0);
    const rates = s.ingestRates();
    for (const [label, r] of [...rates].sort((a, b) => a[0].localeCompare(b[0], undefined, { numeric: true }))) {
      row(`UAV ${label} ingest`, `${fmt(r.scans, 1)} scans/s · ${fmt(r.detections, 1)} det/s`);
    }
    const m = this.metrics;
    if (m) {
      const sum = (name, pred = () => true) => m.filter((x) => x.name === name && pred(x.labels)).reduce((a, x) => a + x.value, 0);
      row("payloads received", `${sum("harrier_payloads_received_total")}`);
      row("scans ingested", `${sum("harrier_scans_ingested_total")}`);
      const drops = new Map();
      for (const x of m.filter((x) => x.name === "harrier_scans_dropped_total")) {
        drops.set(x.labels.reason, (drops.get(x.labels.reason) || 0) + x.value);
      }
      const dropText = [...drops].filter(([, n]) => n > 0).map(([r, n]) => `${r} ${n}`).join(", ");
      row("scans dropped", dropText || "0", !!dropText);
      row("seq lost", `${sum("harrier_seq_lost_total")}`, sum("harrier_seq_lost_total") > 0);
      row("WebSocket clients", `${sum("harrier_ws_clients")}`);
      row("WebSocket drops (all clients)", `${sum("harrier_ws_dropped_total")}`, sum("harrier_ws_dropped_total") > 0);
      row("HTTP refused", `${sum("harrier_http_refused_total")}`);
      row("uptime", `${fmt(sum("harrier_uptime_seconds"), 0)} s`);
    } else if (this.metricsError) {
      row("metrics", this.metricsError, true);
    }
    const trs = this.table.rows;
    if (trs.length !== rows.length) {
      this.table.replaceChildren(...rows.map(() => el("tr", {}, el("td"), el("td"))));
    }
    rows.forEach(([k, v, bad], i) => {
      const tr = this.table.rows[i];
      setText(tr.cells[0], k);
      setText(tr.cells[1], v);
      if (tr.classList.contains("bad") !== bad) tr.classList.toggle("bad", bad);
    });
  }
}

/** A bias term's value ± sd in its unit: metres, mrad (angles), ppm (scales), ms (time offsets). */
export function fmtBias(kind, t) {
  const angle = (kind === "range_bearing" && t.term === "offset1") || (kind !== "range_bearing" && t.term.startsWith("offset"));
  const [f, unit, digits] = t.term === "time_offset" ? [1e3, "ms", 0]
    : t.term.startsWith("scale") ? [1e6, "ppm", 0]
    : angle ? [1e3, "mrad", 2] : [1, "m", 1];
  return `${fmt(t.value * f, digits)} ± ${fmt(t.std * f, digits)} ${unit}`;
}

/** "Sensor biases": each registered sensor's terms ± sd and whether they are observable yet. */
export class BiasesPanel {
  constructor(section, table, store) {
    this.section = section;
    this.table = table;
    this.store = store;
  }

  update() {
    const list = this.store.biases;
    this.section.hidden = list.length === 0;
    const rows = [];
    for (const s of list) {
      const biased = typeof s.biased_prob === "number" ? ` · biased ${(100 * s.biased_prob).toFixed(0)} %` : "";
      rows.push([`${s.vehicle}/${s.sensor}`, `${s.kind} · ${s.updates} updates · ${s.observable ? "observable" : "not observable"}${biased}`, !s.observable, "sensor"]);
      for (const t of s.terms) rows.push([`  ${t.term}`, `${fmtBias(s.kind, t)} · ${t.observable ? "yes" : "no"}`, !t.observable, "term"]);
    }
    if (this.table.rows.length !== rows.length) {
      this.table.replaceChildren(...rows.map(() => el("tr", {}, el("td"), el("td"))));
    }
    rows.forEach(([k, v, bad, kind], i) => {
      const tr = this.table.rows[i];
      tr.dataset.kind = kind;
      setText(tr.cells[0], k);
      setText(tr.cells[1], v);
      if (tr.classList.contains("bad") !== bad) tr.classList.toggle("bad", bad);
    });
  }
}

// --- hand-off laws in the assign form -------------------------------------------------------------

/** The hand-off kinds (`Law` on the API): the track handed to each vehicle's autopilot. */
const HANDOFF_LAWS = [
  ["handoff_orbit", "hand-off: orbit (DO_ORBIT / loiter)"],
  ["handoff_follow", "hand-off: follow (FOLLOW_TARGET)"],
  ["handoff_camera", "hand-off: point camera (ROI)"],
];

/** Adds the hand-off kinds to the assign form's law list (once; the form is in index.html). */
export function addHandoffLaws(select) {
  if (!select) return;
  for (const [value, text] of HANDOFF_LAWS) {
    if ([...select.options].some((o) => o.value === value)) continue;
    select.append(el("option", { value, text }));
  }
}

addHandoffLaws(document.getElementById("assign-law"));
