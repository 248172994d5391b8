// The local grid map: a 2-D canvas in the server's local ENU frame (x East, y North, metres). No
// tiles, no network: a metre grid, a scale bar and a north arrow under the live picture
// (painter.js). Drag to pan, wheel to zoom (about the cursor), double-click to fit; optionally
// follows a track. The geographic map (geomap.js) is the other choice.

import { Painter } from "./painter.js";
import { cssSize, fmtDist, niceStep } from "./util.js";

const BG = "#0c1219";

export class MapView {
  constructor(canvas, store, layers) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.store = store;
    this.center = [0, 0];
    this.scale = 0.25; // px per m
    this.userMoved = false; // the operator panned or zoomed: no more automatic fitting
    this.follow = null; // track id
    this.layers = layers;
    this.painter = new Painter(store, layers);
    this.stats = Painter.emptyStats(0);
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
    return cssSize(this.canvas)[0];
  }
  get height() {
    return cssSize(this.canvas)[1];
  }

  toScreen(x, y) {
    return [this.width / 2 + (x - this.center[0]) * this.scale, this.height / 2 - (y - this.center[1]) * this.scale];
  }
  toScreenCached(_key, x, y) {
    return this.toScreen(x, y);
  }
  toWorld(px, py) {
    return [this.center[0] + (px - this.width / 2) / this.scale, this.center[1] - (py - this.height / 2) / this.scale];
  }

  /** Frames everything known (vehicles, tracks, truth). */
  fit() {
    const e = Painter.extent(this.store);
    if (!e || !this.width) return false;
    const [x0, y0, x1, y1] = e;
    this.center = [(x0 + x1) / 2, (y0 + y1) / 2];
    this.scale = Math.min(this.width / (x1 - x0), this.height / (y1 - y0));
    return true;
  }

  resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(this.width * dpr);
    const h = Math.round(this.height * dpr);
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
    if (!this.width || !this.height) return;
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
    const st = Painter.emptyStats(this.stats.frames + 1);

    this.drawGrid(ctx);
    this.painter.draw(ctx, this, now, st);
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
