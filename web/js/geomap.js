// The geographic map: Leaflet (vendored, web/vendor/leaflet) with the tile sources the server
// names (GET /api/v1/map: an online URL template, its own MBTiles file at /tiles/{z}/{x}/{y}),
// and the live picture (painter.js) drawn over the tiles on one canvas, a custom Leaflet layer
// redrawn every animation frame: each ENU position goes to WGS-84 (geo.js, the frame's origin
// from the same answer) and then to the screen through `map.latLngToContainerPoint` — one canvas
// for thousands of shapes, rather than as many SVG or DOM objects. Drag to pan, wheel to zoom,
// *Fit* to frame everything; optionally follows a track. Zoom animation is off, so that the
// canvas and the tiles always show the same view.

import { EnuFrame, metresPerPixel } from "./geo.js";
import { Painter } from "./painter.js";
import { cssSize } from "./util.js";

const L = window.L;
const RAD = Math.PI / 180;
/** Leaflet's (and Web Mercator's) latitude limit (°). */
const MAX_LAT = 85.0511287798;
/** Where a stored point (a history's, a trail's) keeps its WGS-84 and its pixels in the view. */
const GEODETIC = Symbol("geodetic");

/** The canvas over the map: a Leaflet layer in the map's container, above the tiles. */
const OverlayLayer = L
  ? L.Layer.extend({
      onAdd(map) {
        this.canvas = L.DomUtil.create("canvas", "harrier-overlay");
        map.getContainer().appendChild(this.canvas);
      },
      onRemove() {
        this.canvas.remove();
      },
    })
  : null;

/** Text as HTML (Leaflet shows attributions as HTML). */
function escapeHtml(s) {
  return String(s).replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
}

/** A source's attribution as Leaflet shows it: escaped, OpenStreetMap's linked to its licence. */
function attributionHtml(text) {
  if (!text) return "";
  const t = escapeHtml(text);
  return /openstreetmap/i.test(text) ? `<a href="https://www.openstreetmap.org/copyright">${t}</a>` : t;
}

export class GeoMapView {
  constructor(el, store, layers) {
    this.el = el;
    this.store = store;
    this.layers = layers;
    this.painter = new Painter(store, layers);
    this.stats = Painter.emptyStats(0);
    this.map = null;
    this.frame = null;
    this.follow = null;
    this.userMoved = false;
    this.moving = false; // a view change of ours (not the operator's)
    this.cursor = null;
    this.scale = 1; // px per m at the view's centre
    this.tiles = { loaded: 0, errors: 0, source: null, sources: [] };
    this.note = null;
    this.size = [0, 0];
  }

  /**
   * Builds the map for `body` (GET /api/v1/map): its raster sources as base layers (the first
   * shown; a layer control when there are several), the frame's origin. Without Leaflet, a
   * note and no map.
   */
  init(body) {
    if (!L) {
      this.note = "Leaflet is missing (web/vendor/leaflet): only the local grid";
      return false;
    }
    this.frame = new EnuFrame(body.origin);
    const map = L.map(this.el, { zoomAnimation: false, zoomSnap: 1, minZoom: 2, maxZoom: 21, worldCopyJump: false });
    this.map = map;
    const o = body.origin;
    map.setView([o.lat_deg, o.lon_deg], 15);
    L.control.scale({ imperial: false, position: "bottomleft" }).addTo(map);
    const bases = {};
    for (const s of body.sources) {
      if (!s.raster) continue;
      const opts = { minZoom: s.min_zoom, maxNativeZoom: s.max_zoom, maxZoom: 21, attribution: attributionHtml(s.attribution) };
      // Only where the source has tiles: nothing is asked (and nothing missing) outside.
      if (s.bounds) opts.bounds = L.latLngBounds([s.bounds[1], s.bounds[0]], [s.bounds[3], s.bounds[2]]);
      if (s.url.includes("{s}")) opts.subdomains = "abc";
      const layer = L.tileLayer(s.url, opts);
      layer.on("tileload", () => (this.tiles.loaded += 1));
      layer.on("tileerror", () => (this.tiles.errors += 1));
      layer.on("add", () => (this.tiles.source = s.name));
      const label = `${s.name} (${s.kind === "url" ? "online" : "offline"})`;
      bases[label] = layer;
      this.tiles.sources.push(s.name);
    }
    const names = Object.keys(bases);
    if (names.length) bases[names[0]].addTo(map);
    if (names.length > 1) L.control.layers(bases, null, { position: "topright" }).addTo(map);
    const vector = body.sources.filter((s) => !s.raster).map((s) => s.name);
    if (vector.length && !names.length) this.note = `vector tiles (${vector.join(", ")}) are not drawn by this page`;
    else if (!body.sources.length) this.note = "no tile source configured ([map] in the server's configuration)";
    this.overlay = new OverlayLayer();
    this.overlay.addTo(map);
    this.canvas = this.overlay.canvas;
    this.ctx = this.canvas.getContext("2d");
    // The operator's own moves end the automatic fitting, and dragging ends following.
    map.on("dragstart", () => {
      this.userMoved = true;
      this.setFollow(null);
    });
    map.on("zoomstart", () => {
      if (!this.moving) this.userMoved = true;
    });
    map.on("mousemove", (e) => (this.cursor = e.latlng));
    map.on("mouseout", () => (this.cursor = null));
    return true;
  }

  setFollow(id) {
    this.follow = id;
    if (this.onFollowChange) this.onFollowChange(id);
  }

  get width() {
    return cssSize(this.el)[0];
  }
  get height() {
    return cssSize(this.el)[1];
  }

  /**
   * Canvas pixels of ENU (m), on the ground plane: WGS-84 through the frame (geo.js), then
   * Leaflet's projection of the view (EPSG:3857, `map.project` less the container's pixel
   * origin, read once a frame in `draw`). Not `map.latLngToContainerPoint`, which rounds to
   * whole pixels: 3 m at zoom 15 here, and a moving track would jump from pixel to pixel.
   */
  toScreen(x, y) {
    const g = this.frame.toGeodetic(x, y, this.store.planeZ);
    return this.project(g[0], g[1]);
  }

  /**
   * `toScreen` of a point that never changes (`key`, its array): its WGS-84 is kept, and its
   * pixels until the view changes (a trail or history is thousands of points a frame).
   */
  toScreenCached(key, x, y) {
    let g = key[GEODETIC];
    if (!g || g.frame !== this.frame) {
      g = this.frame.toGeodetic(x, y, this.store.planeZ);
      g.frame = this.frame;
      key[GEODETIC] = g;
    }
    if (g.view !== this.view) {
      g.view = this.view;
      g.px = this.project(g[0], g[1]);
    }
    return g.px;
  }

  /** Canvas pixels of a latitude and longitude (°): Leaflet's spherical Mercator, inlined. */
  project(lat, lon) {
    const v = this.view;
    const s = Math.sin(Math.max(Math.min(lat, MAX_LAT), -MAX_LAT) * RAD);
    return [v.k * (lon * RAD) + v.x0, -v.k * 0.5 * Math.log((1 + s) / (1 - s)) + v.y0];
  }

  /**
   * The view's projection constants: pixels per radian (256 · 2^zoom / 2π) and where the
   * projected origin falls on the canvas, from Leaflet's own state (its pixel origin and the
   * pane's offset), so that `project` agrees with `map.project`.
   */
  readView() {
    const map = this.map;
    const zoom = map.getZoom();
    const k = (256 * 2 ** zoom) / (2 * Math.PI);
    const origin = map.getPixelOrigin();
    const pane = map.containerPointToLayerPoint([0, 0]);
    const view = { k, x0: 128 * 2 ** zoom - origin.x - pane.x, y0: 128 * 2 ** zoom - origin.y - pane.y };
    // The same object while the view stays: `toScreenCached` keeps pixels per view.
    const v = this.view;
    if (!v || v.k !== view.k || v.x0 !== view.x0 || v.y0 !== view.y0) this.view = view;
  }

  /** [lat, lon] under canvas pixels (Leaflet's own inverse; the tests check against it). */
  toLatLng(px, py) {
    const ll = this.map.containerPointToLatLng([px, py]);
    return [ll.lat, ll.lng];
  }

  visible(px, py, r = 0) {
    return px + r >= 0 && py + r >= 0 && px - r <= this.width && py - r <= this.height;
  }

  /** Runs a view change of ours (not counted as the operator's). */
  programmatic(fn) {
    this.moving = true;
    try {
      fn();
    } finally {
      this.moving = false;
    }
  }

  /**
   * Frames everything known (vehicles, tracks, truth). The view changes only when something
   * would be outside it, or when all of it fits a closer zoom level: tiles are not asked again
   * for every small move.
   */
  fit() {
    const e = Painter.extent(this.store);
    if (!e || !this.map || !this.width) return false;
    const sw = this.frame.toGeodetic(e[0], e[1]);
    const ne = this.frame.toGeodetic(e[2], e[3]);
    const b = L.latLngBounds([sw[0], sw[1]], [ne[0], ne[1]]);
    const zoom = Math.min(this.map.getBoundsZoom(b), 19);
    if (zoom !== this.map.getZoom() || !this.map.getBounds().contains(b)) {
      this.programmatic(() => this.map.setView(b.getCenter(), zoom, { animate: false }));
    }
    return true;
  }

  draw(now) {
    if (!this.map || !this.width || !this.height) return;
    if (this.size[0] !== this.width || this.size[1] !== this.height) {
      this.size = [this.width, this.height];
      this.map.invalidateSize({ pan: false });
    }
    if (!this.userMoved && this.follow == null && (this.stats.frames % 30 === 0 || !this.fitted)) {
      this.fitted = this.fit() || this.fitted;
    }
    if (this.follow != null) {
      this.readView();
      const k = this.store.tracks.get(this.follow);
      if (k) {
        const [px, py] = this.toScreen(k.view.state[0], k.view.state[1]);
        const [dx, dy] = [px - this.width / 2, py - this.height / 2];
        if (Math.abs(dx) + Math.abs(dy) > 0.5) this.programmatic(() => this.map.panBy([dx, dy], { animate: false }));
      }
    }
    const dpr = window.devicePixelRatio || 1;
    const [w, h] = [Math.round(this.width * dpr), Math.round(this.height * dpr)];
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
    }
    this.readView();
    const centre = this.map.getCenter();
    this.scale = 1 / metresPerPixel(centre.lat, this.map.getZoom());
    const ctx = this.ctx;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, this.width, this.height);
    const st = Painter.emptyStats(this.stats.frames + 1);
    this.painter.draw(ctx, this, now, st);
    this.drawCursor(ctx);
    st.zoom = this.map.getZoom();
    st.center = [centre.lat, centre.lng];
    this.stats = st;
  }

  /** Latitude, longitude and ENU under the pointer, at the top centre. */
  drawCursor(ctx) {
    if (!this.cursor) return;
    const { lat, lng } = this.cursor;
    const [x, y] = this.frame.toEnu(lat, lng);
    const text = `${Math.abs(lat).toFixed(6)}° ${lat >= 0 ? "N" : "S"}  ${Math.abs(lng).toFixed(6)}° ${lng >= 0 ? "E" : "W"}   E ${x.toFixed(0)} m  N ${y.toFixed(0)} m`;
    ctx.font = "11px ui-monospace, SFMono-Regular, Menlo, monospace";
    const w = ctx.measureText(text).width;
    const x0 = (this.width - w) / 2;
    ctx.fillStyle = "rgba(12,18,25,0.78)";
    ctx.fillRect(x0 - 6, 8, w + 12, 18);
    ctx.fillStyle = "#c9d5e1";
    ctx.fillText(text, x0, 21);
  }
}
