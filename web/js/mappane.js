// The map pane: the geographic map (geomap.js, over tiles) or the local ENU grid (map.js), the
// operator's choice ("Map: geographic | local grid", kept in localStorage), with one set of
// layers and one followed track. The geographic map is the default when the server names a
// tile source (GET /api/v1/map); without one, or on a server without that route, the grid.

import { get } from "./api.js";
import { GeoMapView } from "./geomap.js";
import { MapView } from "./map.js";

const MODE_KEY = "harrier.map";

export class MapPane {
  constructor(root, store) {
    this.root = root;
    this.layers = { truth: true, detections: true, history: true, ellipses: true, bound: true, trails: true, standoff: true, world: true, aircraft: true };
    this.grid = new MapView(root.querySelector("#gridmap"), store, this.layers);
    this.geo = new GeoMapView(root.querySelector("#geomap"), store, this.layers);
    this.mode = "grid";
    this.available = false; // the geographic map could be built
    this.onFollowChange = null;
    for (const v of [this.grid, this.geo]) v.onFollowChange = (id) => this.onFollowChange && this.onFollowChange(id);
    this.buttons = [...document.querySelectorAll("button[data-map-mode]")];
    for (const b of this.buttons) b.addEventListener("click", () => this.setMode(b.dataset.mapMode, true));
  }

  /** Asks the server for its tile sources (when it has the route) and picks the mode. */
  async init(feats) {
    let body = null;
    if (feats.map) {
      try {
        body = await get("map");
      } catch {
        body = null;
      }
    }
    this.available = !!body && this.geo.init(body);
    let saved = null;
    try {
      saved = localStorage.getItem(MODE_KEY);
    } catch {
      /* storage disabled */
    }
    const preferred = saved || (body && body.sources.some((s) => s.raster) ? "geo" : "grid");
    document.getElementById("map-mode").hidden = !this.available;
    this.setMode(this.available ? preferred : "grid", false);
  }

  /** Shows `mode` (`geo` or `grid`), carrying the followed track over. */
  setMode(mode, remember) {
    if (mode !== "geo" && mode !== "grid") return;
    if (mode === "geo" && !this.available) return;
    const follow = this.follow;
    this.mode = mode;
    this.root.dataset.mode = mode;
    this.follow = follow;
    for (const b of this.buttons) b.classList.toggle("on", b.dataset.mapMode === mode);
    const label = document.getElementById("map-label");
    if (label) label.textContent = mode === "geo" ? `Map · WGS-84${this.geo.note ? ` · ${this.geo.note}` : ""}` : "Map · local ENU";
    if (remember) {
      try {
        localStorage.setItem(MODE_KEY, mode);
      } catch {
        /* storage disabled */
      }
    }
  }

  get active() {
    return this.mode === "geo" ? this.geo : this.grid;
  }

  get follow() {
    return this.grid.follow;
  }
  set follow(id) {
    this.grid.follow = id;
    this.geo.follow = id;
  }

  get userMoved() {
    return this.active.userMoved;
  }
  set userMoved(v) {
    this.active.userMoved = v;
  }

  fit() {
    return this.active.fit();
  }

  draw(now) {
    this.active.draw(now);
  }

  /** What the shown map drew (`drawn`: the screen positions of the tracks and UAVs). */
  get stats() {
    const st = this.active.stats;
    return { ...st, mode: this.mode, tiles: this.mode === "geo" ? { ...this.geo.tiles } : null };
  }

  /** [lat, lon] under a pixel of the geographic map (for tests); null on the grid. */
  toLatLng(px, py) {
    return this.mode === "geo" ? this.geo.toLatLng(px, py) : null;
  }
}
