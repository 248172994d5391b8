// The Harrier dashboard: wires the stream and the REST polls into the store, draws the map and the
// 3-D view every animation frame, refreshes the panels a few times a second, and sends the
// operator's actions with the bearer token. `window.harrier` exposes what is drawn (for tests
// and for the curious: open the console).

import { ApiError, Stream, features, get, getText, getToken, request, setToken } from "./js/api.js";
import { MapPane } from "./js/mappane.js";
import { SceneView } from "./js/scene3d.js";
import { Store } from "./js/store.js";
import { BiasesPanel, SeriesPanel, ServicePanel, StandoffPanel, TracksPanel, VehiclesPanel, el, parseMetrics, setText, showResult } from "./js/panels.js";
import { cssSize, fmt } from "./js/util.js";

const $ = (id) => document.getElementById(id);
const store = new Store();
const errors = []; // action errors shown to the operator, newest last

const hook = {
  store,
  errors,
  features: null,
  ws: { state: "connecting", seq: 0, scans: 0, snapshots: 0, reconnects: 0 },
  map: {},
  scene: {},
  fps: 0,
  ready: false,
};
window.harrier = hook;

// --- actions: results and errors ----------------------------------------------------------------

function toast(text, kind = "ok") {
  const t = el("div", { class: `toast ${kind}`, text });
  $("toasts").append(t);
  while ($("toasts").children.length > 4) $("toasts").firstChild.remove();
  setTimeout(() => t.remove(), kind === "bad" ? 7000 : 3500);
}

/** Runs `fn` (a REST call) showing "…" then its result or its error in `node`. */
async function act(node, what, fn, describe) {
  showResult(node, "pending", `${what}…`);
  try {
    const body = await fn();
    const d = describe ? describe(body) : "done";
    // `describe` may say that a 2xx answer is a refusal (a command denied by the vehicle).
    const { kind, text } = typeof d === "string" ? { kind: "ok", text: d } : d;
    showResult(node, kind, text);
    if (kind === "bad") errors.push({ what, message: text, status: null, at: Date.now() });
    return body;
  } catch (e) {
    const msg = e instanceof ApiError ? e.describe() : String(e.message || e);
    showResult(node, "bad", `${what}: ${msg}`);
    errors.push({ what, message: msg, status: e.status ?? null, at: Date.now() });
    if (e.status === 401) markToken(false);
    toast(`${what} failed — ${msg}`, "bad");
    return null;
  }
}

// --- token --------------------------------------------------------------------------------------

function markToken(ok) {
  const s = $("token-state");
  if (ok === false) {
    s.textContent = getToken() ? "token refused" : "no token";
    s.className = "hint bad";
    document.body.dataset.token = "refused";
  } else if (getToken()) {
    s.textContent = ok ? "token accepted" : "saved for this tab";
    s.className = `hint ${ok ? "ok" : ""}`;
    document.body.dataset.token = ok ? "accepted" : "saved";
  } else {
    s.textContent = "needed for actions";
    s.className = "hint";
    document.body.dataset.token = "none";
  }
}

$("token").value = getToken();
markToken(null);
$("token-form").addEventListener("submit", (e) => {
  e.preventDefault();
  setToken($("token").value.trim());
  markToken(null);
  stream.restart(); // servers whose reads need the token take it on the stream too
});

// --- views and layers ---------------------------------------------------------------------------

const map = new MapPane($("map"), store);
hook.mapView = map;
const scene = new SceneView($("scene"), store);
if (scene.error) {
  $("scene-error").hidden = false;
  $("scene-error").textContent = scene.error;
}
const layers = map.layers;
for (const box of document.querySelectorAll("#layers input[data-layer]")) {
  box.addEventListener("change", () => {
    layers[box.dataset.layer] = box.checked;
  });
}
for (const b of document.querySelectorAll(".seg button[data-view]")) {
  b.addEventListener("click", () => {
    for (const o of document.querySelectorAll(".seg button[data-view]")) o.classList.toggle("on", o === b);
    $("panes").dataset.view = b.dataset.view;
  });
}
$("fit").addEventListener("click", () => {
  map.userMoved = false;
  setFollow(null);
  map.fit();
  scene.resetView();
});
$("reset3d").addEventListener("click", () => scene.resetView());

function setFollow(id) {
  map.follow = id;
  $("follow").value = id == null ? "" : String(id);
}
map.onFollowChange = (id) => {
  $("follow").value = id == null ? "" : String(id);
};
$("follow").addEventListener("change", () => {
  const v = $("follow").value;
  setFollow(v ? Number(v) : null);
});

// --- panels -------------------------------------------------------------------------------------

let feats = { truth: false, world: false, assignments: false, commands: false, estimator: true, metrics: true };

/** A MAVLink command's name as the operator knows it (`MAV_CMD_DO_SET_MODE` → `set mode`). */
function commandName(c) {
  return String(c || "").replace(/^MAV_CMD_(NAV_|DO_|COMPONENT_)?/, "").replace(/_/g, " ").toLowerCase();
}

const vehicleActions = {
  command(label, command, altitude, node) {
    const body = { command };
    if (command === "takeoff" && Number.isFinite(altitude) && altitude > 0) body.altitude_m = altitude;
    return act(
      node,
      `${command} UAV ${label}`,
      () => request("POST", `vehicles/${encodeURIComponent(label)}/commands`, body),
      (r) => {
        // 200: the vehicle's COMMAND_ACK; `ok` false when it refused (`denied`, `failed`…).
        const ok = !!(r && (r.ok ?? r.result === "accepted"));
        const n = r && r.attempts;
        const ms = r && Number.isFinite(r.elapsed_ms) ? ` in ${r.elapsed_ms.toFixed(0)} ms` : "";
        const text = `${command}: ${r ? r.result : "?"}${r && r.command ? ` (${commandName(r.command)}` : " ("}${n ? `, ${n} attempt${n > 1 ? "s" : ""}` : ""}${ms})`;
        // The operator wins: a command to a vehicle of an assignment took it out of its slot.
        const released = r && r.released_from_assignment != null ? ` · out of assignment #${r.released_from_assignment} (resume it there)` : "";
        if (ok) markToken(true);
        return { kind: ok ? "ok" : "bad", text: text.replace(" ()", "") + released };
      },
    );
  },
};

let vehiclesPanel;
const tracksPanel = new TracksPanel($("tracks"), store, (id) => setFollow(map.follow === id ? null : id));
const biasesPanel = new BiasesPanel($("biases-panel"), $("biases"), store);
const seriesPanel = new SeriesPanel($("series"), store);
const standoffPanel = new StandoffPanel($("standoff-range"), $("standoff-spacing"), store);
let servicePanel;

// Estimator.
async function loadEstimators() {
  try {
    const body = await get("estimators");
    const sel = $("estimator-name");
    sel.replaceChildren(
      ...body.estimators.map((e) => el("option", { value: e.name, text: `${e.name} — ${e.summary}`, title: e.params.map((p) => `${p.name}: ${p.description}`).join("\n") })),
    );
    if (store.estimator) sel.value = store.estimator.name;
    const assoc = $("estimator-associator");
    assoc.replaceChildren(
      ...(body.associators || []).map((a) => el("option", { value: a.name, text: `${a.name} — ${a.summary}`, title: a.params.map((p) => `${p.name}: ${p.description}`).join("\n") })),
    );
    assoc.hidden = !body.associators;
    if (store.estimator?.associator) assoc.value = store.estimator.associator;
    $("estimator-panel").hidden = false;
  } catch {
    $("estimator-panel").hidden = true;
  }
}

// "ekf + jipda": the track filter and the associator an estimator state names.
function running(e) {
  return e.associator ? `${e.name} + ${e.associator}` : e.name;
}

function parseParams(text) {
  const params = {};
  for (const part of text.split(/[,\s]+/).filter(Boolean)) {
    const m = part.match(/^([\w.-]+)=(.+)$/);
    if (!m || !Number.isFinite(Number(m[2]))) throw new Error(`"${part}" is not name=number`);
    params[m[1]] = Number(m[2]);
  }
  return params;
}

$("estimator-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const node = $("estimator-result");
  let params;
  try {
    params = parseParams($("estimator-params").value);
  } catch (err) {
    showResult(node, "bad", `parameters: ${err.message}`);
    errors.push({ what: "change estimator", message: err.message, status: null, at: Date.now() });
    return;
  }
  const name = $("estimator-name").value;
  const associator = $("estimator-associator").value || undefined;
  const body = await act(node, `change estimator to ${name}`, () => request("PUT", "estimator", { name, associator, params }), (r) => `now running ${running(r)}${Object.keys(r.params || {}).length ? ` (${Object.entries(r.params).map(([k, v]) => `${k}=${v}`).join(", ")})` : ""}`);
  if (body) {
    store.estimator = body;
    markToken(true);
  }
});

// Assignments.
async function refreshAssignments() {
  if (!feats.assignments) return;
  try {
    const body = await get("assignments");
    store.applyAssignments(Array.isArray(body) ? body : body.assignments || []);
  } catch {
    /* shown by the service panel's stream state; the list keeps its last value */
  }
}

const SLOT_TEXT = { waiting: "waiting", arming: "arming", taking_off: "taking off", offboard: "offboard", handed_off: "handed off", lost: "LOST", failed: "FAILED", overridden: "OVERRIDDEN", hold: "hold" };

/** Takes vehicle `vehicle` back into its slot of assignment `id` (it was overridden or failed). */
async function resumeSlot(id, vehicle, node) {
  const r = await act(node, `resume UAV ${vehicle} in assignment ${id}`, () => request("POST", `assignments/${id}/vehicles/${vehicle}/resume`), () => `UAV ${vehicle} resumed in #${id}`);
  if (r) {
    markToken(true);
    store.applyAssignment(r);
  }
}
const assignCards = new Map(); // id → {node, f}

function assignmentCard(a) {
  let c = assignCards.get(a.id);
  if (c) return c;
  const f = {};
  f.state = el("span", { class: "tag", "data-role": "state" });
  f.result = el("span", { class: "result" });
  f.end = el("button", {
    type: "button",
    text: "End",
    "data-action": "end",
    onclick: async () => {
      const r = await act(f.result, `end assignment ${a.id}`, () => request("DELETE", `assignments/${a.id}`), (b) => `ended${b && b.ended_reason ? ` (${b.ended_reason})` : ""}`);
      if (r) {
        markToken(true);
        store.applyAssignment(r);
      }
    },
  });
  f.params = el("div", { class: "note" });
  f.slots = el("div", { class: "slots" });
  f.ended = el("div", { class: "note" });
  const node = el("div", { class: "card", "data-assignment": a.id },
    el("div", { class: "head" },
      el("span", { class: "title", text: `#${a.id}` }),
      el("span", { class: "tag", text: a.law }),
      el("span", { text: `→ T${a.track}` }),
      el("span", { class: "spacer" }),
      f.state,
      f.end),
    f.params, f.slots, f.ended, f.result);
  c = { node, f, slotKey: "" };
  assignCards.set(a.id, c);
  return c;
}

function renderAssignments() {
  const root = $("assignments");
  // Newest first; ended ones after the active ones, at most 5 of them.
  const list = [...store.assignments.values()].sort((x, y) => (x.state === y.state ? y.id - x.id : x.state === "active" ? -1 : 1));
  const shown = list.filter((a, i) => a.state === "active" || i < list.findIndex((b) => b.state !== "active") + 5);
  const ids = new Set(shown.map((a) => a.id));
  for (const [id, c] of assignCards) {
    if (!ids.has(id)) {
      c.node.remove();
      assignCards.delete(id);
    }
  }
  let prev = null;
  for (const a of shown) {
    const { node, f } = assignmentCard(a);
    if (prev ? prev.nextSibling !== node : root.firstChild !== node) {
      if (prev) prev.after(node);
      else root.prepend(node);
    }
    prev = node;
    const active = a.state === "active";
    setText(f.state, a.state);
    f.state.className = `tag ${active ? "ok" : ""}`;
    node.dataset.state = a.state;
    f.end.hidden = !active;
    node.classList.toggle("ended", !active);
    setText(f.params, `R ${fmt(a.radius_m, 0)} m · H ${fmt(a.height_m, 0)} m · spacing ${fmt(a.spacing_deg, 0)}° · ${fmt(a.speed_m_s, 1)} m/s · ${a.orbit}`);
    setText(f.ended, active ? "" : `ended${a.ended_reason ? `: ${a.ended_reason}` : ""}`);
    const slots = a.vehicles || [];
    const c = assignCards.get(a.id);
    const key = slots.map((x) => x.vehicle).join(",");
    if (c.slotKey !== key) {
      f.slots.replaceChildren(
        ...slots.map((x) => el("div", { class: "slot", "data-vehicle": x.vehicle },
          el("span", { class: "k", text: `UAV ${x.vehicle}` }), el("span", { class: "tag" }), el("span", { class: "v" }),
          el("button", { type: "button", text: "Resume", "data-action": "resume", hidden: true, onclick: () => resumeSlot(a.id, x.vehicle, f.result) }))),
      );
      c.slotKey = key;
    }
    slots.forEach((x, i) => {
      const row = f.slots.children[i];
      const tag = row.children[1];
      setText(tag, SLOT_TEXT[x.state] || x.state);
      tag.className = `tag ${x.state === "offboard" ? "ok" : x.state === "lost" || x.state === "failed" || x.state === "overridden" ? "bad" : x.state === "hold" ? "" : "warn"}`;
      row.dataset.state = x.state;
      const parts = [];
      const out = x.state === "overridden" || x.state === "failed";
      const o = x.overridden;
      if (o) parts.push(`${o.by === "api" ? "operator" : o.by === "router_client" ? "router client" : "vehicle"}: ${o.from_mode || "?"} → ${o.to_mode || "?"}${o.disarmed ? " (disarmed)" : ""}`);
      if (!out && Number.isFinite(x.range_error_m)) parts.push(`r−R ${x.range_error_m >= 0 ? "+" : ""}${fmt(x.range_error_m, 1)} m`);
      if (!out && Number.isFinite(x.phase_deg)) parts.push(`φ ${fmt(x.phase_deg, 0)}°`);
      if (x.error) parts.push(x.error);
      setText(row.children[2], parts.join(" · "));
      row.children[2].title = o ? o.detail : x.error || "";
      row.children[3].hidden = !(active && out);
    });
  }
  const empty = root.querySelector(".empty");
  if (!shown.length && !empty) root.append(el("p", { class: "empty", text: "No assignment." }));
  if (shown.length && empty) empty.remove();
}

$("assign-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const vehicles = [...document.querySelectorAll("#assign-vehicles input:checked")].map((i) => Number(i.value));
  const num = (id) => ($(id).value.trim() === "" ? undefined : Number($(id).value));
  const body = { vehicles, track: Number($("assign-track").value), law: $("assign-law").value, orbit: $("assign-orbit").value };
  for (const [k, id] of [["radius_m", "assign-r"], ["height_m", "assign-h"], ["spacing_deg", "assign-spacing"], ["speed_m_s", "assign-speed"]]) {
    const v = num(id);
    if (v !== undefined) body[k] = v;
  }
  const node = $("assign-result");
  if (!vehicles.length || !$("assign-track").value) {
    showResult(node, "bad", "pick at least one vehicle and a track");
    errors.push({ what: "assign", message: "nothing picked", status: null, at: Date.now() });
    return;
  }
  const bad = Object.entries(body).find(([, v]) => typeof v === "number" && !Number.isFinite(v));
  if (bad) {
    showResult(node, "bad", `${bad[0]} is not a number`);
    errors.push({ what: "assign", message: `${bad[0]} is not a number`, status: null, at: Date.now() });
    return;
  }
  const r = await act(node, "assign", () => request("POST", "assignments", body), (a) => `assignment #${a.id} ${a.state || "created"}: UAV ${(a.vehicles || []).map((x) => x.vehicle).join(", ")} → T${a.track}`);
  if (r) {
    markToken(true);
    store.applyAssignment(r);
    hook.lastAssignment = r.id;
    for (const i of document.querySelectorAll("#assign-vehicles input:checked")) i.checked = false;
  }
});

function updateAssignForm() {
  if (!feats.assignments) return;
  const vroot = $("assign-vehicles");
  // The vehicles the GCS link hears (those that can fly an assignment).
  const linked = [...store.vehicles.values()].filter((v) => v.link);
  const labels = linked.map((v) => v.label).sort((a, b) => a.localeCompare(b, undefined, { numeric: true }));
  if (vroot.dataset.labels !== labels.join(",")) {
    const checked = new Set([...vroot.querySelectorAll("input:checked")].map((i) => i.value));
    vroot.replaceChildren(...labels.map((l) => el("label", { "data-vehicle": l }, el("input", { type: "checkbox", value: l, checked: checked.has(l) }), ` ${l}`)));
    vroot.dataset.labels = labels.join(",");
  }
  if (!labels.length && !vroot.textContent) vroot.textContent = "none with a MAVLink link";
  for (const label of vroot.querySelectorAll("label[data-vehicle]")) {
    const busy = store.slotOf(label.dataset.vehicle);
    const t = busy ? `in assignment #${busy.assignment.id}` : "";
    if (label.title !== t) label.title = t;
    label.classList.toggle("busy", !!busy);
  }
  const tsel = $("assign-track");
  const ids = store.confirmed().map((k) => k.id).sort((a, b) => a - b);
  if (tsel.dataset.ids !== ids.join(",")) {
    const cur = tsel.value;
    tsel.replaceChildren(...ids.map((id) => el("option", { value: String(id), text: `T${id}` })));
    if (ids.map(String).includes(cur)) tsel.value = cur;
    tsel.dataset.ids = ids.join(",");
  }
  renderAssignments();
}

// Lost links, second sources claiming a vehicle's id, and vehicles back from a new address: a
// banner while any is so (with an Accept button for a new address), and a toast on each event.
function updateAlerts() {
  const links = [...store.vehicles.values()].filter((v) => v.link);
  const lost = links.filter((v) => v.link.state === "lost").map((v) => v.label);
  const lines = [];
  if (lost.length) lines.push({ text: `Link lost: UAV ${lost.join(", ")} — nothing heard for ${lost.map((l) => fmt(store.vehicles.get(l).link.last_seen_s, 0)).join(", ")} s` });
  const conflicts = links.filter((v) => v.link.identity && v.link.identity.conflict);
  for (const v of conflicts) {
    const c = v.link.identity.conflict;
    lines.push({ text: `Identity conflict: ${c.address} claims system id ${v.label}, which ${v.link.address} holds — its ${c.frames} frames refused, nothing sent to it` });
  }
  const moved = links.filter((v) => v.link.identity && v.link.identity.state === "unconfirmed");
  for (const v of moved) {
    lines.push({ text: `UAV ${v.label} speaks from a new address ${v.link.address} (was ${v.link.identity.previous_address || "?"}): not flown by the guidance until accepted`, accept: v.label });
  }
  const banner = $("alerts");
  banner.hidden = !lines.length;
  const key = JSON.stringify(lines);
  if (banner.dataset.key !== key) {
    banner.dataset.key = key;
    banner.replaceChildren(...lines.map((l) => el("div", { class: "alert-line" }, el("span", { text: l.text }),
      l.accept ? el("button", { type: "button", text: "Accept", "data-action": "accept", onclick: () => acceptVehicle(l.accept) }) : "")));
  }
  document.body.dataset.lost = lost.join(",");
  document.body.dataset.conflicts = conflicts.map((v) => v.label).join(",");
}

async function acceptVehicle(label) {
  const r = await act(el("span"), `accept UAV ${label}`, () => request("POST", `vehicles/${encodeURIComponent(label)}/accept`), (b) => (b && b.accepted ? `UAV ${label} accepted` : "nothing to accept"));
  if (r) {
    markToken(true);
    toast(`UAV ${label}: new address accepted`);
  }
}

function onVehicleEvent(e) {
  store.applyVehicleEvent(e);
  if (e.event === "lost") toast(`UAV ${e.vehicle}: link lost`, "bad");
  else if (e.event === "recovered") toast(`UAV ${e.vehicle}: link recovered`);
  else if (e.event === "conflict") toast(`UAV ${e.vehicle}: ${e.detail || "a second source claims its id"}`, "bad");
  else if (e.event === "moved") toast(`UAV ${e.vehicle}: ${e.detail || "heard from a new address"} — accept it to fly it`, "bad");
}

function updateFollowSelect() {
  const sel = $("follow");
  const ids = store.confirmed().map((k) => k.id).sort((a, b) => a - b);
  if (sel.dataset.ids !== ids.join(",")) {
    sel.replaceChildren(el("option", { value: "", text: "—" }), ...ids.map((id) => el("option", { value: String(id), text: `T${id}` })));
    sel.dataset.ids = ids.join(",");
  }
  sel.value = map.follow == null ? "" : String(map.follow);
  if (map.follow != null && !store.tracks.has(map.follow)) setFollow(null);
}

// --- stream -------------------------------------------------------------------------------------

let lastVehiclesMsg = 0;
const stream = new Stream(
  (msg) => {
    switch (msg.type) {
      case "snapshot":
        store.applySnapshot(msg);
        if (store.estimator && $("estimator-name").value !== store.estimator.name && document.activeElement !== $("estimator-name")) {
          $("estimator-name").value = store.estimator.name;
        }
        if (store.estimator?.associator && $("estimator-associator").value !== store.estimator.associator && document.activeElement !== $("estimator-associator")) {
          $("estimator-associator").value = store.estimator.associator;
        }
        break;
      case "scan":
        store.applyScan(msg);
        break;
      case "vehicles":
        lastVehiclesMsg = performance.now();
        store.applyVehicles(msg);
        break;
      case "vehicle_event":
        if (msg.event) onVehicleEvent(msg.event);
        break;
      case "assignment":
        if (msg.assignment) store.applyAssignment(msg.assignment);
        else refreshAssignments();
        break;
      default:
        break; // unknown types are for newer pages
    }
  },
  (state) => {
    document.body.dataset.wsState = state;
    const pill = $("conn");
    pill.className = `pill pill-${state}`;
    pill.textContent = { open: "live", connecting: "connecting…", closed: "disconnected — retrying" }[state];
    if (state === "open") pollNow();
  },
);

// Track details (history before this page saw the track, the OBE bound) for the confirmed tracks.
const detailsPending = new Set();
async function fetchDetails(id) {
  if (detailsPending.has(id)) return;
  detailsPending.add(id);
  try {
    const d = await get(`tracks/${id}`);
    store.mergeHistory(id, d.history, d.bound ?? null);
  } catch {
    /* a track deleted meanwhile */
  } finally {
    detailsPending.delete(id);
  }
}
store.onConfirmed = (id) => {
  if (stream.state === "open") setTimeout(() => fetchDetails(id), 50);
};

// --- polls --------------------------------------------------------------------------------------

let pollTick = 0;
function pollNow() {
  pollTick = 0;
  poll();
}

// The top bar's loss badges, from /metrics: detection scans the server dropped (every reason
// but `sensor_filtered`, a deliberate filter; red while the count grows, amber once it stops),
// and a recording that is off or failing.
const dropsPill = document.getElementById("drops");
const recordingPill = document.getElementById("recording");
let droppedBefore = null;
function showLosses(m) {
  const byReason = new Map();
  for (const x of m) {
    if (x.name !== "harrier_scans_dropped_total" || x.labels.reason === "sensor_filtered") continue;
    byReason.set(x.labels.reason, (byReason.get(x.labels.reason) || 0) + x.value);
  }
  const total = [...byReason.values()].reduce((a, n) => a + n, 0);
  const rising = droppedBefore !== null && total > droppedBefore;
  droppedBefore = total;
  dropsPill.hidden = total === 0;
  dropsPill.dataset.dropped = String(total);
  dropsPill.dataset.rising = String(rising);
  dropsPill.textContent = `dropped ${total} scan${total === 1 ? "" : "s"}`;
  dropsPill.className = `pill ${rising ? "pill-closed" : "pill-connecting"}`;
  dropsPill.title =
    "Detection scans the server dropped, by reason: " +
    [...byReason].filter(([, n]) => n > 0).map(([r, n]) => `${r} ${n}`).join(", ") +
    (rising ? " (dropping now)" : "");
  const up = m.find((x) => x.name === "harrier_recorder_up");
  const errors = m.filter((x) => x.name === "harrier_recorder_errors_total").reduce((a, x) => a + x.value, 0);
  recordingPill.hidden = !(up && (up.value === 0 || errors > 0));
  recordingPill.textContent = up && up.value === 0 ? "recording OFF" : `recording: ${errors} failed writes`;
}

async function poll() {
  pollTick += 1;
  if (stream.state !== "open") return; // the server is away: nothing to ask
  const jobs = [];
  // Vehicles: the stream's `vehicles` messages when the server sends them, else GET /vehicles.
  if (performance.now() - lastVehiclesMsg > 3000 && pollTick % 2 === 1) {
    jobs.push(get("vehicles").then((b) => store.applyVehicles(b)).catch(() => {}));
  }
  // Bias estimates (sensor registration): at connection, then with the scans that carry them.
  if (pollTick % 30 === 1) jobs.push(get("biases").then((b) => store.applyBiases(b)).catch(() => {}));
  if (feats.truth) jobs.push(get("truth").then((b) => store.applyTruth(b)).catch(() => {}));
  // The world is static; asked again now and then in case the server was restarted with another.
  if (feats.world && pollTick % 30 === 1) jobs.push(get("world").then((b) => store.applyWorld(b)).catch(() => {}));
  // Manned aircraft (ADS-B): once a second while the layer is on.
  if (feats.aircraft && layers.aircraft) jobs.push(get("aircraft").then((b) => store.applyAircraft(b)).catch(() => {}));
  if (feats.metrics && pollTick % 2 === 1 && servicePanel) {
    jobs.push(
      getText("metrics")
        .then((t) => {
          servicePanel.metrics = parseMetrics(t);
          servicePanel.metricsError = null;
          showLosses(servicePanel.metrics);
        })
        .catch((e) => {
          servicePanel.metricsError = e instanceof ApiError ? e.describe() : String(e);
        }),
    );
  }
  // Assignments: in the stream's `vehicles` messages; polled only when those do not come.
  if (feats.assignments && pollTick % 2 === 0 && performance.now() - lastVehiclesMsg > 3000) jobs.push(refreshAssignments());
  // The OBE bounds change with every update: refresh them for the confirmed tracks (≤ 20).
  if (layers.bound && pollTick % 2 === 0) {
    for (const k of store.confirmed().slice(0, 20)) if (k.view.updated) jobs.push(fetchDetails(k.id));
  }
  await Promise.all(jobs);
}

// --- render loop --------------------------------------------------------------------------------

let frames = 0;
let renders = 0;
let fpsSince = performance.now();
const frameWork = []; // ms of main-thread work per frame over the last second
function frame(now) {
  const t0 = performance.now();
  store.prune(now);
  map.draw(now);
  scene.update(now, layers);
  if (cssSize(scene.canvas)[0] && scene.render(now)) renders += 1;
  frameWork.push(performance.now() - t0);
  frames += 1;
  if (now - fpsSince >= 1000) {
    hook.fps = (1000 * frames) / (now - fpsSince);
    hook.sceneFps = (1000 * renders) / (now - fpsSince);
    const sorted = frameWork.splice(0).sort((a, b) => a - b);
    // The page's own work per frame (drawing, scene updates, WebGL calls), 90th percentile: what
    // it leaves of a frame's budget, whatever the rasteriser (GPU or software) then takes.
    hook.frameMs = sorted.length ? sorted[Math.floor(0.9 * (sorted.length - 1))] : 0;
    scene.adapt(hook.fps);
    hook.sceneQuality = { resolution: scene.quality, dataFps: scene.dataFps, software: !!scene.software };
    frames = 0;
    renders = 0;
    fpsSince = now;
  }
  publish();
  requestAnimationFrame(frame);
}

/** What the page draws, for tests: `window.harrier` and data attributes. */
function publish() {
  const m = map.stats;
  const sc = scene.stats;
  hook.map = { ...m };
  hook.scene = { ...sc, available: !!scene.renderer };
  hook.ws = { state: stream.state, seq: store.seq, scans: store.scans, snapshots: store.snapshots, reconnects: stream.reconnects, messages: stream.messages };
  const mc = $("map").dataset;
  mc.tracks = m.tracks;
  mc.ellipses = m.ellipses;
  mc.uavs = m.uavs;
  mc.aircraft = m.aircraft;
  const sd = $("scene").dataset;
  sd.tracks = sc.tracks;
  sd.ellipsoids = sc.ellipsoids;
  sd.uavs = sc.uavs;
  document.body.dataset.seq = store.seq;
  document.body.dataset.scans = store.scans;
}

function updatePanels() {
  setText($("seq"), `${store.seq || "–"}`);
  const rates = store.ingestRates();
  let total = 0;
  for (const r of rates.values()) total += r.scans;
  setText($("scanrate"), total.toFixed(1));
  setText($("ntracks"), `${store.confirmed().length}`);
  setText($("nuavs"), `${[...store.vehicles.values()].filter((v) => v.position).length}`);
  setText($("fps"), hook.fps.toFixed(0));
  if (store.estimator) setText($("estimator-running"), `running: ${running(store.estimator)}${Object.keys(store.estimator.params || {}).length ? ` ${JSON.stringify(store.estimator.params)}` : ""}`);
  vehiclesPanel?.update();
  tracksPanel.update(map.follow);
  seriesPanel.update();
  standoffPanel.update();
  servicePanel?.update();
  biasesPanel.update();
  updateAlerts();
  updateAssignForm();
  updateFollowSelect();
}

// --- start --------------------------------------------------------------------------------------

async function start() {
  feats = await features();
  hook.features = feats;
  vehiclesPanel = new VehiclesPanel($("vehicles"), store, feats.commands ? vehicleActions : null);
  servicePanel = new ServicePanel($("service"), store, stream);
  $("assign-panel").hidden = !feats.assignments;
  $("standoff-panel").hidden = !feats.assignments;
  document.body.dataset.features = Object.entries(feats).filter(([, v]) => v).map(([k]) => k).join(" ");
  await map.init(feats);
  stream.connect();
  loadEstimators();
  setInterval(updatePanels, 250);
  setInterval(poll, 1000);
  requestAnimationFrame(frame);
  hook.ready = true;
  document.body.dataset.ready = "true";
}

start();
