// The live picture, drawn on a 2-D canvas through a projection: tracks with their 95 % ellipses,
// velocity and history, OBE bounds, detections and bearing rays, UAVs with heading and trail,
// truth, the roads and no-fly discs of GET /world, standoff circles, formation links, ADS-B
// aircraft. The local grid (map.js) and the geographic map (geomap.js) both draw it, each with
// its own projection `p`: `toScreen(x, y)` (ENU metres → canvas pixels), `toScreenCached(key, x,
// y)` (the same for a stored point that never changes, `key` its array: history, trails, truth,
// roads; a projection may keep what it computed for it), `scale` (pixels per metre there),
// `visible(px, py, r)` and `follow` (the followed track's id).

import { Store } from "./store.js";
import { LABELLED_UAVS, SWARM_TRAIL, colorFor, detectionPoint, detectionRay, fmtDist } from "./util.js";

export class Painter {
  constructor(store, layers) {
    this.store = store;
    this.layers = layers;
    this.p = null;
  }

  /** The stats of an empty frame: what each layer drew, and where (for tests). */
  static emptyStats(frames) {
    return { tracks: 0, ellipses: 0, bounds: 0, uavs: 0, detections: 0, rays: 0, standoff: 0, vectors: 0, roads: 0, obstacles: 0, links: 0, aircraft: 0, frames, drawn: { tracks: [], uavs: [] } };
  }

  /**
   * The ENU rectangle [x0, y0, x1, y1] (m) that frames everything known — vehicles, tracks,
   * truth — with 250 m around it and at least 500 m a side; null when nothing is known.
   */
  static extent(store) {
    const pts = [];
    for (const v of store.vehicles.values()) if (v.position) pts.push(v.position);
    for (const k of store.tracks.values()) pts.push(k.view.state);
    for (const t of store.truth.values()) if (t.last) pts.push(t.last.position);
    if (!pts.length) return null;
    let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
    for (const p of pts) {
      x0 = Math.min(x0, p[0]);
      x1 = Math.max(x1, p[0]);
      y0 = Math.min(y0, p[1]);
      y1 = Math.max(y1, p[1]);
    }
    const [cx, cy] = [(x0 + x1) / 2, (y0 + y1) / 2];
    const hw = Math.max(x1 - x0 + 500, 500) / 2;
    const hh = Math.max(y1 - y0 + 500, 500) / 2;
    return [cx - hw, cy - hh, cx + hw, cy + hh];
  }

  /**
   * Begins a path through stored points (`pts[i][at]`, `pts[i][at + 1]`: ENU x, y), leaving out
   * those less than a pixel from the last one kept (a history of 200 updates is a few pixels
   * long at a wide view); the last point is always in.
   */
  tracePath(ctx, pts, at, begin = true) {
    if (begin) ctx.beginPath();
    let [lx, ly] = [NaN, NaN];
    const n = pts.length;
    for (let i = 0; i < n; i += 1) {
      const p = pts[i];
      const [x, y] = this.p.toScreenCached(p, p[at], p[at + 1]);
      if (i === 0) ctx.moveTo(x, y);
      else if (Math.abs(x - lx) + Math.abs(y - ly) >= 1 || i === n - 1) ctx.lineTo(x, y);
      else continue;
      [lx, ly] = [x, y];
    }
  }

  /** Draws every layer that is on through projection `p`, counting into `st`. */
  draw(ctx, p, now, st) {
    this.p = p;
    const layers = this.layers;
    if (layers.world) this.drawWorld(ctx, st);
    if (layers.standoff) this.drawStandoff(ctx, st);
    if (layers.truth) this.drawTruth(ctx);
    if (layers.detections) this.drawDetections(ctx, now, st);
    this.drawTracks(ctx, st);
    if (layers.aircraft) this.drawAircraft(ctx, st);
    this.drawVehicles(ctx, st);
  }

  drawTruth(ctx) {
    for (const target of this.store.truth.values()) {
      const pts = target.samples;
      if (pts.length < 2) continue;
      ctx.strokeStyle = "rgba(235,240,245,0.55)";
      ctx.lineWidth = 1.5;
      ctx.setLineDash([6, 5]);
      this.tracePath(ctx, pts, 1);
      ctx.stroke();
      ctx.setLineDash([]);
      const last = pts[pts.length - 1];
      const [px, py] = this.p.toScreen(last[1], last[2]);
      ctx.fillStyle = "rgba(240,244,248,0.9)";
      ctx.beginPath();
      ctx.rect(px - 3.5, py - 3.5, 7, 7);
      ctx.fill();
      ctx.font = "11px system-ui, sans-serif";
      ctx.fillText(`truth ${target.id}`, px + 7, py + 14);
    }
  }

  drawDetections(ctx, now, st) {
    const planeZ = this.store.planeZ;
    for (const d of this.store.detections) {
      const a = Store.fade(d, now);
      if (a <= 0) continue;
      const ray = detectionRay(d.kind, d.z, d.platform, planeZ);
      if (ray) {
        const [x0, y0] = this.p.toScreen(ray[0][0], ray[0][1]);
        const [x1, y1] = this.p.toScreen(ray[1][0], ray[1][1]);
        ctx.strokeStyle = `rgba(255,196,90,${(0.5 * a).toFixed(3)})`;
        ctx.lineWidth = 1;
        ctx.beginPath();
        ctx.moveTo(x0, y0);
        ctx.lineTo(x1, y1);
        ctx.stroke();
        st.rays += 1;
        continue;
      }
      const p = detectionPoint(d.kind, d.z, d.platform, planeZ);
      if (!p) continue;
      const [px, py] = this.p.toScreen(p[0], p[1]);
      if (!this.p.visible(px, py, 4)) continue;
      ctx.fillStyle = `rgba(255,196,90,${(0.85 * a).toFixed(3)})`;
      ctx.beginPath();
      ctx.arc(px, py, 2.2, 0, 2 * Math.PI);
      ctx.fill();
      st.detections += 1;
    }
  }

  drawTracks(ctx, st) {
    const tracks = [...this.store.tracks.values()];
    // Tentative tracks first, faint; confirmed on top.
    tracks.sort((a, b) => (a.view.status === b.view.status ? a.id - b.id : a.view.status === "confirmed" ? 1 : -1));
    for (const k of tracks) {
      const confirmed = k.view.status === "confirmed";
      const color = confirmed ? colorFor(k.id) : "rgba(150,165,180,0.7)";
      const [x, y] = k.view.state;
      const [px, py] = this.p.toScreen(x, y);
      if (this.layers.history && k.history.length > 1) {
        ctx.strokeStyle = color;
        ctx.globalAlpha = confirmed ? 0.55 : 0.3;
        ctx.lineWidth = 1.5;
        this.tracePath(ctx, k.history, 1);
        ctx.lineTo(px, py);
        ctx.stroke();
        ctx.globalAlpha = 1;
      }
      if (this.layers.bound && k.bound && confirmed) {
        const b = k.bound;
        const [bx, by] = this.p.toScreen(b.center[0], b.center[1]);
        const ra = Math.max(b.semi_axes[0] * this.p.scale, 1);
        const rb = Math.max(b.semi_axes[1] * this.p.scale, 1);
        if (this.p.visible(bx, by, ra)) {
          ctx.strokeStyle = "rgba(255,170,60,0.95)";
          ctx.lineWidth = 1.3;
          ctx.setLineDash([4, 3]);
          ctx.beginPath();
          ctx.ellipse(bx, by, ra, rb, -b.angle_rad, 0, 2 * Math.PI);
          ctx.stroke();
          ctx.setLineDash([]);
          st.bounds += 1;
        }
      }
      const e = k.ellipse;
      const ra = e ? Math.max(e.semi_axes[0] * this.p.scale, 1.5) : 0;
      if (!this.p.visible(px, py, Math.max(ra, 30))) continue;
      if (this.layers.ellipses && e) {
        const rb = Math.max(e.semi_axes[1] * this.p.scale, 1.5);
        ctx.beginPath();
        ctx.ellipse(px, py, ra, rb, -e.angle_rad, 0, 2 * Math.PI);
        ctx.fillStyle = color;
        ctx.globalAlpha = confirmed ? 0.14 : 0.06;
        ctx.fill();
        ctx.globalAlpha = confirmed ? 0.95 : 0.5;
        ctx.strokeStyle = color;
        ctx.lineWidth = confirmed ? 1.6 : 1;
        ctx.stroke();
        ctx.globalAlpha = 1;
        if (confirmed) st.ellipses += 1;
      }
      // Velocity vector: where the track will be in 10 s.
      const [vx, vy] = [k.view.state[3], k.view.state[4]];
      const [qx, qy] = this.p.toScreen(x + 10 * vx, y + 10 * vy);
      ctx.strokeStyle = color;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      ctx.moveTo(px, py);
      ctx.lineTo(qx, qy);
      ctx.stroke();
      ctx.fillStyle = color;
      ctx.beginPath();
      ctx.arc(px, py, confirmed ? 4 : 2.5, 0, 2 * Math.PI);
      ctx.fill();
      if (confirmed) {
        st.tracks += 1;
        st.drawn.tracks.push({ id: k.id, t: k.view.t, x, y, px: [px, py] });
        const speed = Math.hypot(vx, vy);
        const label = `T${k.id}  ${speed.toFixed(1)} m/s`;
        ctx.font = "600 11.5px system-ui, sans-serif";
        const w = ctx.measureText(label).width;
        const lx = px + 9;
        const ly = py - 9;
        ctx.fillStyle = "rgba(12,18,25,0.78)";
        ctx.fillRect(lx - 3, ly - 12, w + 6, 16);
        ctx.fillStyle = color;
        ctx.fillText(label, lx, ly);
        if (this.p.follow === k.id) {
          ctx.strokeStyle = "rgba(255,255,255,0.8)";
          ctx.setLineDash([3, 3]);
          ctx.beginPath();
          ctx.arc(px, py, Math.max(ra, 12) + 6, 0, 2 * Math.PI);
          ctx.stroke();
          ctx.setLineDash([]);
        }
      }
    }
  }

  /**
   * The static world (GET /world): roads as bands of their width (at least 3 px) with a dashed
   * centre line, obstacles as hatched red discs with their radius.
   */
  drawWorld(ctx, st) {
    const { roads, obstacles } = this.store.world;
    for (const road of roads) {
      if (!road.points || road.points.length < 2) continue;
      const path = () => this.tracePath(ctx, road.points, 0);
      ctx.lineJoin = "round";
      ctx.lineCap = "round";
      ctx.strokeStyle = "rgba(150,160,175,0.22)";
      ctx.lineWidth = Math.max(3, (road.width_m ?? 6) * this.p.scale);
      path();
      ctx.stroke();
      ctx.strokeStyle = "rgba(220,225,235,0.35)";
      ctx.lineWidth = 1;
      ctx.setLineDash([6, 8]);
      path();
      ctx.stroke();
      ctx.setLineDash([]);
      st.roads += 1;
    }
    for (const o of obstacles) {
      const [px, py] = this.p.toScreen(o.x_m, o.y_m);
      const r = Math.max(3, o.radius_m * this.p.scale);
      if (!this.p.visible(px, py, r)) continue;
      ctx.save();
      ctx.beginPath();
      ctx.arc(px, py, r, 0, 2 * Math.PI);
      ctx.fillStyle = "rgba(255,93,93,0.10)";
      ctx.fill();
      ctx.clip();
      ctx.strokeStyle = "rgba(255,93,93,0.35)";
      ctx.lineWidth = 1;
      for (let d = -r; d < r; d += 7) {
        ctx.beginPath();
        ctx.moveTo(px + d, py - r);
        ctx.lineTo(px + d + 2 * r, py + r);
        ctx.stroke();
      }
      ctx.restore();
      ctx.strokeStyle = "rgba(255,93,93,0.8)";
      ctx.lineWidth = 1.3;
      ctx.beginPath();
      ctx.arc(px, py, r, 0, 2 * Math.PI);
      ctx.stroke();
      ctx.fillStyle = "rgba(255,140,140,0.9)";
      ctx.font = "10.5px system-ui, sans-serif";
      ctx.fillText(`no-fly ${fmtDist(o.radius_m)}`, px + r * 0.72 + 4, py - r * 0.72);
      st.obstacles += 1;
    }
  }

  /**
   * A formation's links ([BOT]: one range regulator per line of sight): between every two of its
   * vehicles (solid, with the distance) and from each to the track it surrounds (dashed).
   */
  drawFormationLinks(ctx, a, k, st) {
    const pts = (a.vehicles || [])
      .map((slot) => this.store.vehicles.get(String(slot.vehicle)))
      .filter((v) => v && v.position)
      .map((v) => v.position);
    ctx.font = "10px system-ui, sans-serif";
    for (let i = 0; i < pts.length; i += 1) {
      for (let j = i + 1; j < pts.length; j += 1) {
        const [x0, y0] = this.p.toScreen(pts[i][0], pts[i][1]);
        const [x1, y1] = this.p.toScreen(pts[j][0], pts[j][1]);
        ctx.strokeStyle = "rgba(255,200,90,0.7)";
        ctx.lineWidth = 1.4;
        ctx.beginPath();
        ctx.moveTo(x0, y0);
        ctx.lineTo(x1, y1);
        ctx.stroke();
        const d = Math.hypot(pts[j][0] - pts[i][0], pts[j][1] - pts[i][1]);
        ctx.fillStyle = "rgba(255,210,120,0.9)";
        ctx.fillText(fmtDist(d), (x0 + x1) / 2 + 4, (y0 + y1) / 2 - 4);
        st.links += 1;
      }
      if (k) {
        const [x0, y0] = this.p.toScreen(pts[i][0], pts[i][1]);
        const [x1, y1] = this.p.toScreen(k.view.state[0], k.view.state[1]);
        ctx.strokeStyle = "rgba(255,200,90,0.4)";
        ctx.lineWidth = 1;
        ctx.setLineDash([3, 5]);
        ctx.beginPath();
        ctx.moveTo(x0, y0);
        ctx.lineTo(x1, y1);
        ctx.stroke();
        ctx.setLineDash([]);
        st.links += 1;
      }
    }
  }

  /**
   * Each active assignment: its standoff circle (radius R around the assigned track's estimate)
   * and the velocity last commanded to each of its vehicles (an arrow of 10 s of flight).
   */
  drawStandoff(ctx, st) {
    for (const a of this.store.assignments.values()) {
      if (a.state !== "active") continue;
      const k = this.store.tracks.get(a.track);
      if (a.law === "formation") this.drawFormationLinks(ctx, a, k, st);
      const r = a.radius_m;
      if (k && Number.isFinite(r)) {
        const [px, py] = this.p.toScreen(k.view.state[0], k.view.state[1]);
        ctx.strokeStyle = "rgba(120,220,255,0.75)";
        ctx.lineWidth = 1.3;
        ctx.setLineDash([8, 6]);
        ctx.beginPath();
        ctx.arc(px, py, r * this.p.scale, 0, 2 * Math.PI);
        ctx.stroke();
        ctx.setLineDash([]);
        ctx.fillStyle = "rgba(120,220,255,0.85)";
        ctx.font = "10.5px system-ui, sans-serif";
        // Below the circle, centred (the UAVs' labels sit right of them, on the circle).
        const text = `#${a.id} ${a.law.toUpperCase()} R ${fmtDist(r)} H ${fmtDist(a.height_m)}`;
        ctx.fillText(text, px - ctx.measureText(text).width / 2, py + r * this.p.scale + 14);
        st.standoff += 1;
      }
      for (const slot of a.vehicles || []) {
        const v = this.store.vehicles.get(String(slot.vehicle));
        const u = slot.commanded_velocity;
        if (!v || !v.position || !u || slot.state !== "offboard") continue;
        const [x0, y0] = this.p.toScreen(v.position[0], v.position[1]);
        const [x1, y1] = this.p.toScreen(v.position[0] + 10 * u[0], v.position[1] + 10 * u[1]);
        const len = Math.hypot(x1 - x0, y1 - y0);
        if (len < 2) continue;
        ctx.strokeStyle = "#5ef0c0";
        ctx.fillStyle = "#5ef0c0";
        ctx.lineWidth = 2;
        ctx.beginPath();
        ctx.moveTo(x0, y0);
        ctx.lineTo(x1, y1);
        ctx.stroke();
        const ang = Math.atan2(y1 - y0, x1 - x0);
        const hl = Math.min(8, len / 2);
        ctx.beginPath();
        ctx.moveTo(x1, y1);
        ctx.lineTo(x1 - hl * Math.cos(ang - 0.45), y1 - hl * Math.sin(ang - 0.45));
        ctx.lineTo(x1 - hl * Math.cos(ang + 0.45), y1 - hl * Math.sin(ang + 0.45));
        ctx.closePath();
        ctx.fill();
        st.vectors += 1;
      }
    }
  }

  /**
   * Manned aircraft of the ADS-B feed: a cyan aircraft glyph along its course, labelled with its
   * callsign (else its address) and flight level; at the list's time, carried on by its age.
   */
  drawAircraft(ctx, st) {
    ctx.font = "10px ui-monospace, SFMono-Regular, Menlo, monospace";
    for (const a of this.store.aircraft) {
      const s = a.state;
      const age = a.age_s || 0;
      const [px, py] = this.p.toScreen(s[0] + s[3] * age, s[1] + s[4] * age);
      if (!this.p.visible(px, py, 20)) continue;
      ctx.save();
      ctx.translate(px, py);
      ctx.rotate(Math.atan2(s[3], s[4]));
      ctx.beginPath();
      ctx.moveTo(0, -9);
      ctx.lineTo(1.6, -3);
      ctx.lineTo(8, 1);
      ctx.lineTo(1.6, 0.5);
      ctx.lineTo(1.2, 6);
      ctx.lineTo(3.5, 8);
      ctx.lineTo(-3.5, 8);
      ctx.lineTo(-1.2, 6);
      ctx.lineTo(-1.6, 0.5);
      ctx.lineTo(-8, 1);
      ctx.lineTo(-1.6, -3);
      ctx.closePath();
      ctx.fillStyle = a.age_s > 10 ? "rgba(110,200,230,0.45)" : "#6ec8e6";
      ctx.fill();
      ctx.restore();
      ctx.fillStyle = "rgba(140,210,235,0.85)";
      const fl = Math.round(a.altitude_m / 0.3048 / 100);
      ctx.fillText(`${a.callsign || a.icao} FL${String(Math.max(fl, 0)).padStart(3, "0")}`, px + 10, py - 4);
      st.aircraft += 1;
    }
  }

  drawVehicles(ctx, st) {
    const shown = [];
    for (const v of this.store.vehicles.values()) if (v.position) shown.push(v);
    const swarm = shown.length > LABELLED_UAVS;
    // Trails: one path for all of them (a swarm's: their newest points).
    if (this.layers.trails) {
      ctx.strokeStyle = "rgba(200,215,235,0.35)";
      ctx.lineWidth = 1.2;
      ctx.beginPath();
      for (const v of shown) {
        const t = swarm && v.trail.length > SWARM_TRAIL ? v.trail.slice(-SWARM_TRAIL) : v.trail;
        if (t.length > 1) this.tracePath(ctx, t, 1, false);
      }
      ctx.stroke();
    }
    // Bodies: an arrow along the heading (clockwise from North = clockwise on screen from up),
    // one path per colour; a soft shadow only while few are drawn.
    const onScreen = [];
    for (const v of shown) {
      const [px, py] = this.p.toScreen(v.position[0], v.position[1]);
      if (this.p.visible(px, py, 20)) onScreen.push({ v, px, py, lost: v.link?.state === "lost" });
    }
    for (const lost of [false, true]) {
      ctx.beginPath();
      let any = false;
      for (const u of onScreen) {
        if (u.lost !== lost) continue;
        any = true;
        const h = u.v.heading ?? 0;
        const [c, s] = [Math.cos(h), Math.sin(h)];
        const at = (x, y) => [u.px + x * c - y * s, u.py + x * s + y * c];
        ctx.moveTo(...at(0, -11));
        ctx.lineTo(...at(7.5, 8));
        ctx.lineTo(...at(0, 4.5));
        ctx.lineTo(...at(-7.5, 8));
        ctx.closePath();
      }
      if (!any) continue;
      ctx.fillStyle = lost ? "#ff5d5d" : "#f4f7fb";
      if (!swarm) {
        ctx.shadowColor = "rgba(0,0,0,0.6)";
        ctx.shadowBlur = 4;
      }
      ctx.fill();
      ctx.shadowBlur = 0;
      ctx.strokeStyle = "#0c1219";
      ctx.lineWidth = 1;
      ctx.stroke();
    }
    // No heading known: a ring around the arrow.
    ctx.strokeStyle = "rgba(244,247,251,0.5)";
    ctx.beginPath();
    for (const u of onScreen) {
      if (u.v.heading != null) continue;
      ctx.moveTo(u.px + 14, u.py);
      ctx.arc(u.px, u.py, 14, 0, 2 * Math.PI);
    }
    ctx.stroke();
    ctx.font = "600 11.5px system-ui, sans-serif";
    for (const { v, px, py, lost } of onScreen) {
      if (!swarm || lost) {
        const alt = v.position[2] - this.store.planeZ;
        const label = `UAV ${v.label}  ${alt.toFixed(0)} m${lost ? "  LINK LOST" : ""}`;
        const w = ctx.measureText(label).width;
        ctx.fillStyle = "rgba(12,18,25,0.78)";
        ctx.fillRect(px + 12, py + 4, w + 6, 16);
        ctx.fillStyle = lost ? "#ff5d5d" : "#f4f7fb";
        ctx.fillText(label, px + 15, py + 16);
      }
      st.uavs += 1;
      st.drawn.uavs.push({ label: v.label, x: v.position[0], y: v.position[1], px: [px, py] });
    }
  }
}
