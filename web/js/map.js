// The map: a 2-D canvas in the server's local ENU frame (x East, y North, metres). No tiles, no
// network: a metre grid, a scale bar and a north arrow. Drag to pan, wheel to zoom (about the
// cursor), double-click to fit; optionally follows a track.

import { Store } from "./store.js";
import { colorFor, detectionPoint, detectionRay, fmtDist, niceStep } from "./util.js";

const BG = "#0c1219";

export class MapView {
  constructor(canvas, store) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.store = store;
    this.center = [0, 0];
    this.scale = 0.25; // px per m
    this.userMoved = false; // the operator panned or zoomed: no more automatic fitting
    this.follow = null; // track id
    this.layers = { truth: true, detections: true, history: true, ellipses: true, bound: true, trails: true, standoff: true, world: true, aircraft: true };
    this.stats = { tracks: 0, ellipses: 0, bounds: 0, uavs: 0, detections: 0, rays: 0, frames: 0 };
    this.cursor = null;
    this.dpr = 1;
    this.installInput();
  }

  installInput() {
    const c = this.canvas;
    let drag = null;
    c.addEventListener("pointerdown", (e) => {
      drag = { x: e.clientX, y: e.clientY, center: [...this.center] };
      c.setPointerCapture(e.pointerId);
      c.classList.add("dragging");
    });
    c.addEventListener("pointermove", (e) => {
      const r = c.getBoundingClientRect();
      this.cursor = this.toWorld(e.clientX - r.left, e.clientY - r.top);
      if (!drag) return;
      const dx = e.clientX - drag.x;
      const dy = e.clientY - drag.y;
      if (Math.abs(dx) + Math.abs(dy) > 2) {
        this.userMoved = true;
        this.setFollow(null);
      }
      this.center = [drag.center[0] - dx / this.scale, drag.center[1] + dy / this.scale];
    });
    const end = (e) => {
      drag = null;
      c.classList.remove("dragging");
      if (c.hasPointerCapture(e.pointerId)) c.releasePointerCapture(e.pointerId);
    };
    c.addEventListener("pointerup", end);
    c.addEventListener("pointercancel", end);
    c.addEventListener("pointerleave", () => (this.cursor = null));
    c.addEventListener(
      "wheel",
      (e) => {
        e.preventDefault();
        const r = c.getBoundingClientRect();
        const px = e.clientX - r.left;
        const py = e.clientY - r.top;
        const before = this.toWorld(px, py);
        const f = Math.exp(-e.deltaY * 0.0015);
        this.scale = Math.min(50, Math.max(0.005, this.scale * f));
        const after = this.toWorld(px, py);
        if (this.follow == null) {
          this.center[0] += before[0] - after[0];
          this.center[1] += before[1] - after[1];
        }
        this.userMoved = true;
      },
      { passive: false },
    );
    c.addEventListener("dblclick", () => {
      this.userMoved = false;
      this.setFollow(null);
      this.fit();
    });
  }

  setFollow(id) {
    this.follow = id;
    if (this.onFollowChange) this.onFollowChange(id);
  }

  get width() {
    return this.canvas.clientWidth;
  }
  get height() {
    return this.canvas.clientHeight;
  }

  toScreen(x, y) {
    return [this.width / 2 + (x - this.center[0]) * this.scale, this.height / 2 - (y - this.center[1]) * this.scale];
  }
  toWorld(px, py) {
    return [this.center[0] + (px - this.width / 2) / this.scale, this.center[1] - (py - this.height / 2) / this.scale];
  }

  /** Frames everything known (vehicles, tracks, truth). */
  fit() {
    const pts = [];
    for (const v of this.store.vehicles.values()) if (v.position) pts.push(v.position);
    for (const k of this.store.tracks.values()) pts.push(k.view.state);
    for (const t of this.store.truth.values()) if (t.last) pts.push(t.last.position);
    if (!pts.length || !this.width) return false;
    let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
    for (const p of pts) {
      x0 = Math.min(x0, p[0]);
      x1 = Math.max(x1, p[0]);
      y0 = Math.min(y0, p[1]);
      y1 = Math.max(y1, p[1]);
    }
    const margin = 250;
    const w = Math.max(x1 - x0 + 2 * margin, 500);
    const h = Math.max(y1 - y0 + 2 * margin, 500);
    this.center = [(x0 + x1) / 2, (y0 + y1) / 2];
    this.scale = Math.min(this.width / w, this.height / h);
    return true;
  }

  resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(this.canvas.clientWidth * dpr);
    const h = Math.round(this.canvas.clientHeight * dpr);
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
    }
    this.dpr = dpr;
  }

  visible(px, py, r = 0) {
    return px + r >= 0 && py + r >= 0 && px - r <= this.width && py - r <= this.height;
  }

  draw(now) {
    if (!this.canvas.clientWidth || !this.canvas.clientHeight) return;
    this.resize();
    const s = this.store;
    if (!this.userMoved && this.follow == null && (this.stats.frames % 30 === 0 || !this.fitted)) {
      this.fitted = this.fit() || this.fitted;
    }
    if (this.follow != null) {
      const k = s.tracks.get(this.follow);
      if (k) this.center = [k.view.state[0], k.view.state[1]];
    }
    const ctx = this.ctx;
    ctx.setTransform(this.dpr, 0, 0, this.dpr, 0, 0);
    ctx.fillStyle = BG;
    ctx.fillRect(0, 0, this.width, this.height);
    const st = { tracks: 0, ellipses: 0, bounds: 0, uavs: 0, detections: 0, rays: 0, standoff: 0, vectors: 0, roads: 0, obstacles: 0, links: 0, aircraft: 0, frames: this.stats.frames + 1 };

    this.drawGrid(ctx);
    if (this.layers.world) this.drawWorld(ctx, st);
    if (this.layers.standoff) this.drawStandoff(ctx, st);
    if (this.layers.truth) this.drawTruth(ctx);
    if (this.layers.detections) this.drawDetections(ctx, now, st);
    this.drawTracks(ctx, st);
    if (this.layers.aircraft) this.drawAircraft(ctx, st);
    this.drawVehicles(ctx, st);
    this.drawScaleBar(ctx);
    this.drawNorthArrow(ctx);
    this.drawCursor(ctx);
    this.stats = st;
  }

  drawGrid(ctx) {
    const step = niceStep(110 / this.scale);
    const [wx0, wy1] = this.toWorld(0, 0);
    const [wx1, wy0] = this.toWorld(this.width, this.height);
    ctx.lineWidth = 1;
    const major = step * 5;
    for (const [sp, style] of [
      [step, "rgba(120,150,180,0.07)"],
      [major, "rgba(120,150,180,0.16)"],
    ]) {
      ctx.strokeStyle = style;
      ctx.beginPath();
      for (let x = Math.ceil(wx0 / sp) * sp; x <= wx1; x += sp) {
        const [px] = this.toScreen(x, 0);
        ctx.moveTo(Math.round(px) + 0.5, 0);
        ctx.lineTo(Math.round(px) + 0.5, this.height);
      }
      for (let y = Math.ceil(wy0 / sp) * sp; y <= wy1; y += sp) {
        const [, py] = this.toScreen(0, y);
        ctx.moveTo(0, Math.round(py) + 0.5);
        ctx.lineTo(this.width, Math.round(py) + 0.5);
      }
      ctx.stroke();
    }
    // The frame's origin.
    const [ox, oy] = this.toScreen(0, 0);
    if (this.visible(ox, oy, 20)) {
      ctx.strokeStyle = "rgba(160,190,220,0.45)";
      ctx.beginPath();
      ctx.moveTo(ox - 8, oy);
      ctx.lineTo(ox + 8, oy);
      ctx.moveTo(ox, oy - 8);
      ctx.lineTo(ox, oy + 8);
      ctx.stroke();
      ctx.fillStyle = "rgba(160,190,220,0.6)";
      ctx.font = "10px ui-monospace, SFMono-Regular, Menlo, monospace";
      ctx.fillText("origin", ox + 5, oy + 13);
    }
    // Coordinates of the major lines along the top and left edges.
    ctx.fillStyle = "rgba(150,175,200,0.55)";
    ctx.font = "10px ui-monospace, SFMono-Regular, Menlo, monospace";
    ctx.textBaseline = "top";
    for (let x = Math.ceil(wx0 / major) * major; x <= wx1; x += major) {
      const [px] = this.toScreen(x, 0);
      if (px > 40) ctx.fillText(`E ${fmtDist(x)}`, px + 3, 4);
    }
    ctx.textBaseline = "bottom";
    for (let y = Math.ceil(wy0 / major) * major; y <= wy1; y += major) {
      const [, py] = this.toScreen(0, y);
      if (py > 30) ctx.fillText(`N ${fmtDist(y)}`, 4, py - 2);
    }
    ctx.textBaseline = "alphabetic";
  }

  drawTruth(ctx) {
    for (const target of this.store.truth.values()) {
      const pts = target.samples;
      if (pts.length < 2) continue;
      ctx.strokeStyle = "rgba(235,240,245,0.55)";
      ctx.lineWidth = 1.5;
      ctx.setLineDash([6, 5]);
      ctx.beginPath();
      pts.forEach((p, i) => {
        const [px, py] = this.toScreen(p[1], p[2]);
        if (i) ctx.lineTo(px, py);
        else ctx.moveTo(px, py);
      });
      ctx.stroke();
      ctx.setLineDash([]);
      const last = pts[pts.length - 1];
      const [px, py] = this.toScreen(last[1], last[2]);
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
        const [x0, y0] = this.toScreen(ray[0][0], ray[0][1]);
        const [x1, y1] = this.toScreen(ray[1][0], ray[1][1]);
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
      const [px, py] = this.toScreen(p[0], p[1]);
      if (!this.visible(px, py, 4)) continue;
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
      const [px, py] = this.toScreen(x, y);
      if (this.layers.history && k.history.length > 1) {
        ctx.strokeStyle = color;
        ctx.globalAlpha = confirmed ? 0.55 : 0.3;
        ctx.lineWidth = 1.5;
        ctx.beginPath();
        k.history.forEach((p, i) => {
          const [hx, hy] = this.toScreen(p[1], p[2]);
          if (i) ctx.lineTo(hx, hy);
          else ctx.moveTo(hx, hy);
        });
        ctx.lineTo(px, py);
        ctx.stroke();
        ctx.globalAlpha = 1;
      }
      if (this.layers.bound && k.bound && confirmed) {
        const b = k.bound;
        const [bx, by] = this.toScreen(b.center[0], b.center[1]);
        const ra = Math.max(b.semi_axes[0] * this.scale, 1);
        const rb = Math.max(b.semi_axes[1] * this.scale, 1);
        if (this.visible(bx, by, ra)) {
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
      const ra = e ? Math.max(e.semi_axes[0] * this.scale, 1.5) : 0;
      if (!this.visible(px, py, Math.max(ra, 30))) continue;
      if (this.layers.ellipses && e) {
        const rb = Math.max(e.semi_axes[1] * this.scale, 1.5);
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
      const [qx, qy] = this.toScreen(x + 10 * vx, y + 10 * vy);
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
        if (this.follow === k.id) {
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
      const path = () => {
        ctx.beginPath();
        road.points.forEach((p, i) => {
          const [x, y] = this.toScreen(p[0], p[1]);
          if (i) ctx.lineTo(x, y);
          else ctx.moveTo(x, y);
        });
      };
      ctx.lineJoin = "round";
      ctx.lineCap = "round";
      ctx.strokeStyle = "rgba(150,160,175,0.22)";
      ctx.lineWidth = Math.max(3, (road.width_m ?? 6) * this.scale);
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
      const [px, py] = this.toScreen(o.x_m, o.y_m);
      const r = Math.max(3, o.radius_m * this.scale);
      if (!this.visible(px, py, r)) continue;
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
        const [x0, y0] = this.toScreen(pts[i][0], pts[i][1]);
        const [x1, y1] = this.toScreen(pts[j][0], pts[j][1]);
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
        const [x0, y0] = this.toScreen(pts[i][0], pts[i][1]);
        const [x1, y1] = this.toScreen(k.view.state[0], k.view.state[1]);
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
        const [px, py] = this.toScreen(k.view.state[0], k.view.state[1]);
        ctx.strokeStyle = "rgba(120,220,255,0.75)";
        ctx.lineWidth = 1.3;
        ctx.setLineDash([8, 6]);
        ctx.beginPath();
        ctx.arc(px, py, r * this.scale, 0, 2 * Math.PI);
        ctx.stroke();
        ctx.setLineDash([]);
        ctx.fillStyle = "rgba(120,220,255,0.85)";
        ctx.font = "10.5px system-ui, sans-serif";
        // Below the circle, centred (the UAVs' labels sit right of them, on the circle).
        const text = `#${a.id} ${a.law.toUpperCase()} R ${fmtDist(r)} H ${fmtDist(a.height_m)}`;
        ctx.fillText(text, px - ctx.measureText(text).width / 2, py + r * this.scale + 14);
        st.standoff += 1;
      }
      for (const slot of a.vehicles || []) {
        const v = this.store.vehicles.get(String(slot.vehicle));
        const u = slot.commanded_velocity;
        if (!v || !v.position || !u || slot.state !== "offboard") continue;
        const [x0, y0] = this.toScreen(v.position[0], v.position[1]);
        const [x1, y1] = this.toScreen(v.position[0] + 10 * u[0], v.position[1] + 10 * u[1]);
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
      const [px, py] = this.toScreen(s[0] + s[3] * age, s[1] + s[4] * age);
      if (!this.visible(px, py, 20)) continue;
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
    for (const v of this.store.vehicles.values()) {
      if (!v.position) continue;
      const lost = v.link && v.link.state === "lost";
      const color = lost ? "#ff5d5d" : "#f4f7fb";
      if (this.layers.trails && v.trail.length > 1) {
        ctx.strokeStyle = "rgba(200,215,235,0.35)";
        ctx.lineWidth = 1.2;
        ctx.beginPath();
        v.trail.forEach((p, i) => {
          const [tx, ty] = this.toScreen(p[1], p[2]);
          if (i) ctx.lineTo(tx, ty);
          else ctx.moveTo(tx, ty);
        });
        ctx.stroke();
      }
      const [px, py] = this.toScreen(v.position[0], v.position[1]);
      if (!this.visible(px, py, 20)) continue;
      ctx.save();
      ctx.translate(px, py);
      const heading = v.heading ?? 0;
      ctx.rotate(heading); // clockwise from North = clockwise on screen from up
      ctx.beginPath();
      ctx.moveTo(0, -11);
      ctx.lineTo(7.5, 8);
      ctx.lineTo(0, 4.5);
      ctx.lineTo(-7.5, 8);
      ctx.closePath();
      ctx.fillStyle = color;
      ctx.shadowColor = "rgba(0,0,0,0.6)";
      ctx.shadowBlur = 4;
      ctx.fill();
      ctx.shadowBlur = 0;
      ctx.strokeStyle = "#0c1219";
      ctx.lineWidth = 1;
      ctx.stroke();
      ctx.restore();
      if (v.heading == null) {
        ctx.strokeStyle = "rgba(244,247,251,0.5)";
        ctx.beginPath();
        ctx.arc(px, py, 14, 0, 2 * Math.PI);
        ctx.stroke();
      }
      const alt = v.position[2] - this.store.planeZ;
      const label = `UAV ${v.label}  ${alt.toFixed(0)} m${lost ? "  LINK LOST" : ""}`;
      ctx.font = "600 11.5px system-ui, sans-serif";
      const w = ctx.measureText(label).width;
      ctx.fillStyle = "rgba(12,18,25,0.78)";
      ctx.fillRect(px + 12, py + 4, w + 6, 16);
      ctx.fillStyle = color;
      ctx.fillText(label, px + 15, py + 16);
      st.uavs += 1;
    }
  }

  drawScaleBar(ctx) {
    const target = 140 / this.scale;
    const len = niceStep(target);
    const w = len * this.scale;
    const x = 16;
    const y = this.height - 22;
    ctx.fillStyle = "rgba(12,18,25,0.75)";
    ctx.fillRect(x - 8, y - 20, w + 16, 32);
    ctx.strokeStyle = "#dfe7ef";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(x, y - 5);
    ctx.lineTo(x, y);
    ctx.lineTo(x + w, y);
    ctx.lineTo(x + w, y - 5);
    ctx.moveTo(x + w / 2, y);
    ctx.lineTo(x + w / 2, y - 3);
    ctx.stroke();
    ctx.fillStyle = "#dfe7ef";
    ctx.font = "11px system-ui, sans-serif";
    ctx.textAlign = "center";
    ctx.fillText(fmtDist(len), x + w / 2, y - 8);
    ctx.textAlign = "left";
  }

  drawNorthArrow(ctx) {
    const x = this.width - 30;
    const y = 38;
    ctx.fillStyle = "rgba(12,18,25,0.75)";
    ctx.beginPath();
    ctx.arc(x, y, 20, 0, 2 * Math.PI);
    ctx.fill();
    ctx.beginPath();
    ctx.moveTo(x, y - 14);
    ctx.lineTo(x + 6, y + 7);
    ctx.lineTo(x, y + 3);
    ctx.closePath();
    ctx.fillStyle = "#ff6b6b";
    ctx.fill();
    ctx.beginPath();
    ctx.moveTo(x, y - 14);
    ctx.lineTo(x - 6, y + 7);
    ctx.lineTo(x, y + 3);
    ctx.closePath();
    ctx.fillStyle = "#dfe7ef";
    ctx.fill();
    ctx.font = "600 10px system-ui, sans-serif";
    ctx.textAlign = "center";
    ctx.fillText("N", x, y + 17);
    ctx.textAlign = "left";
  }

  drawCursor(ctx) {
    if (!this.cursor) return;
    const text = `E ${this.cursor[0].toFixed(0)} m   N ${this.cursor[1].toFixed(0)} m`;
    ctx.font = "11px ui-monospace, SFMono-Regular, Menlo, monospace";
    const w = ctx.measureText(text).width;
    ctx.fillStyle = "rgba(12,18,25,0.75)";
    ctx.fillRect(this.width - w - 18, this.height - 26, w + 12, 18);
    ctx.fillStyle = "#c9d5e1";
    ctx.fillText(text, this.width - w - 12, this.height - 13);
  }
}
