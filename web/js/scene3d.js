// The 3-D view (three.js, vendored): scene coordinates are the server's ENU metres with z up.
// Terrain grid, UAVs at altitude with a drop line and trail, tracks with their 95 % covariance
// ellipsoids (translucent; planar tracks as thin discs), set-membership (OBE) bounds as amber
// cylinders over their planar ellipse, camera rays from each UAV to its recent detections.
// Orbit with the left button, pan with the right, zoom with the wheel.

import * as THREE from "three";
import { OrbitControls } from "../vendor/three/OrbitControls.js";
import { Store } from "./store.js";
import { LABELLED_UAVS, SWARM_TRAIL, colorHex, cssSize, detectionPoint, detectionRay } from "./util.js";

/** Half-thickness (m) of the disc drawn for a planar track's 95 % ellipse. */
const DISC_HALF_M = 2.8;

/**
 * The axes of a track's 95 % region as three scaled column vectors: its `ellipsoid_95`, else a
 * thin disc over its `ellipse_95` (planar tracks); null when the server sent neither.
 */
function regionAxes(view) {
  const e3 = view.ellipsoid_95;
  if (e3) return e3.axes.map((u, i) => u.map((c) => c * e3.semi_axes[i]));
  const e = view.ellipse_95;
  if (!e) return null;
  const [c, s] = [Math.cos(e.angle_rad), Math.sin(e.angle_rad)];
  const [a, b] = e.semi_axes;
  return [
    [a * c, a * s, 0],
    [-b * s, b * c, 0],
    [0, 0, DISC_HALF_M],
  ];
}

const MAX_RAYS = 600;
const MAX_CMDS = 64;
/** Most renders per second for data changes (the camera's own moves render at every frame). */
const DATA_FPS = 15;

/** Whether WebGL is rendered in software (SwiftShader, llvmpipe): then no multisampling. */
function softwareWebGL() {
  try {
    const gl = document.createElement("canvas").getContext("webgl2");
    if (!gl) return false;
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : "";
    gl.getExtension("WEBGL_lose_context")?.loseContext();
    return /swiftshader|llvmpipe|software/i.test(name);
  } catch {
    return false;
  }
}

/** A line whose points change: one preallocated buffer, grown by doubling, drawn up to `n`. */
function setLine(line, points, zOffset = 0) {
  const n = points.length;
  let attr = line.geometry.getAttribute("position");
  if (!attr || attr.count < n) {
    const cap = Math.max(64, 2 ** Math.ceil(Math.log2(Math.max(n, 1))));
    line.geometry.dispose();
    line.geometry = new THREE.BufferGeometry();
    attr = new THREE.BufferAttribute(new Float32Array(cap * 3), 3);
    attr.setUsage(THREE.DynamicDrawUsage);
    line.geometry.setAttribute("position", attr);
  }
  for (let i = 0; i < n; i++) {
    const p = points[i];
    attr.setXYZ(i, p[1], p[2], p[3] + zOffset);
  }
  attr.needsUpdate = true;
  line.geometry.setDrawRange(0, n);
}

/** Most rewrites per second of the UAVs' trails (history: a few a second look continuous). */
const TRAIL_HZ = 4;

/**
 * The attribute `name` (`size` numbers per vertex) of a line's geometry with room for `n`
 * vertices: the one it has, else a new geometry's, grown by doubling (the line's other attributes
 * are copied into the new geometry, grown alike).
 */
function growAttribute(line, name, size, n) {
  let attr = line.geometry.getAttribute(name);
  if (attr && attr.count >= n) return attr;
  const cap = Math.max(64, 2 ** Math.ceil(Math.log2(Math.max(n, 1))));
  const old = line.geometry;
  line.geometry = new THREE.BufferGeometry();
  for (const [k, a] of Object.entries(old.attributes)) {
    if (k === name) continue;
    const grown = new THREE.BufferAttribute(new Float32Array(cap * a.itemSize), a.itemSize);
    grown.array.set(a.array.subarray(0, Math.min(a.array.length, grown.array.length)));
    grown.setUsage(THREE.DynamicDrawUsage);
    line.geometry.setAttribute(k, grown);
  }
  old.dispose();
  attr = new THREE.BufferAttribute(new Float32Array(cap * size), size);
  attr.setUsage(THREE.DynamicDrawUsage);
  line.geometry.setAttribute(name, attr);
  return attr;
}

export class SceneView {
  constructor(canvas, store) {
    this.canvas = canvas;
    this.store = store;
    this.stats = { tracks: 0, ellipsoids: 0, bounds: 0, uavs: 0, rays: 0, frames: 0 };
    this.renderer = null;
    try {
      this.software = softwareWebGL();
      this.renderer = new THREE.WebGLRenderer({ canvas, antialias: !this.software, alpha: false, powerPreference: "low-power" });
    } catch (e) {
      this.error = `WebGL is not available: ${e.message || e}`;
      return;
    }
    this.renderer.setClearColor(0x0b1118);
    this.scene = new THREE.Scene();
    this.scene.fog = new THREE.Fog(0x0b1118, 6000, 16000);
    this.camera = new THREE.PerspectiveCamera(45, 1, 5, 50000);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(-1500, -2500, 1800);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.enableDamping = true;
    this.controls.dampingFactor = 0.12;
    this.controls.maxPolarAngle = Math.PI * 0.495;
    this.controls.addEventListener("start", () => (this.userMoved = true));
    this.controls.addEventListener("change", () => (this.cameraMoved = true));
    this.userMoved = false;
    // Rendering on demand: when the camera moves (at once) or the data changed (at most
    // DATA_FPS times a second), so that a software WebGL leaves the map and the panels smooth.
    this.cameraMoved = true;
    this.dataVersion = -1;
    this.lastRender = 0;
    this.renders = 0;
    // Adapted to the page's frame rate (see `adapt`): resolution scale and data render rate.
    this.quality = 1;
    this.dataFps = DATA_FPS;

    this.scene.add(new THREE.HemisphereLight(0xdde8ff, 0x202830, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 1.4);
    sun.position.set(2000, -1500, 4000);
    this.scene.add(sun);

    this.ground = new THREE.Group();
    this.scene.add(this.ground);
    this.buildGround(10000, 250);

    this.trackObjs = new Map();
    this.uavLabels = new Map(); // label → { label: sprite } of the UAVs that carry a label
    this.truthObjs = new Map();

    // Shared geometry.
    this.sphere = new THREE.SphereGeometry(1, 32, 18);
    this.marker = new THREE.SphereGeometry(9, 16, 10);
    this.cylinder = new THREE.CylinderGeometry(1, 1, 1, 48, 1, true);
    this.cylinder.rotateX(Math.PI / 2); // axis along z
    this.uavGeom = new THREE.ConeGeometry(16, 48, 4); // apex along +y (North) before the heading turn
    this.uavGeom.scale(1, 1, 0.35);
    // Every UAV in three draw calls, whatever their number: the bodies as one instanced mesh,
    // the drop lines and the trails each as one line-segment buffer.
    this.uavBodies = null; // grown by `uavCapacity`
    this.uavPlaced = []; // per instance: [x, y, z, heading]
    this.uavMaterial = new THREE.MeshPhongMaterial({ color: 0xffffff, emissive: 0x334455 });
    this.drops = new THREE.LineSegments(
      new THREE.BufferGeometry(),
      new THREE.LineDashedMaterial({ color: 0x9fb3c8, dashSize: 12, gapSize: 8, transparent: true, opacity: 0.6 }),
    );
    this.drops.frustumCulled = false;
    this.trails = new THREE.LineSegments(
      new THREE.BufferGeometry(),
      new THREE.LineBasicMaterial({ color: 0xc8d7eb, transparent: true, opacity: 0.45 }),
    );
    this.trails.frustumCulled = false;
    this.trailKeys = new Map(); // label → the newest trail point drawn
    this.scene.add(this.drops, this.trails);

    // Camera rays: one line-segment buffer rewritten per frame.
    const rayGeom = new THREE.BufferGeometry();
    rayGeom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(MAX_RAYS * 6), 3));
    rayGeom.setAttribute("color", new THREE.BufferAttribute(new Float32Array(MAX_RAYS * 8), 4));
    this.rays = new THREE.LineSegments(
      rayGeom,
      new THREE.LineBasicMaterial({ vertexColors: true, transparent: true, depthWrite: false }),
    );
    this.rays.frustumCulled = false;
    this.scene.add(this.rays);

    // Standoff: a ring of radius R at height H over each assigned track, and the commanded
    // velocities (10 s of flight) of its vehicles, one line-segment buffer rewritten per frame.
    this.ringGeom = new THREE.BufferGeometry().setFromPoints(
      Array.from({ length: 96 }, (_, i) => new THREE.Vector3(Math.cos((i / 96) * 2 * Math.PI), Math.sin((i / 96) * 2 * Math.PI), 0)),
    );
    this.rings = new Map(); // assignment id → LineLoop
    const cmdGeom = new THREE.BufferGeometry();
    cmdGeom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(MAX_CMDS * 6), 3));
    this.cmds = new THREE.LineSegments(cmdGeom, new THREE.LineBasicMaterial({ color: 0x5ef0c0 }));
    this.cmds.frustumCulled = false;
    this.scene.add(this.cmds);
  }

  buildGround(size, cell) {
    this.ground.clear();
    const plane = new THREE.Mesh(
      new THREE.PlaneGeometry(size, size),
      new THREE.MeshBasicMaterial({ color: 0x111b24, transparent: true, opacity: 0.92, depthWrite: false }),
    );
    this.ground.add(plane);
    const grid = new THREE.GridHelper(size, Math.round(size / cell), 0x3a5268, 0x1d2b38);
    grid.rotation.x = Math.PI / 2; // GridHelper lies in x–z; ours in x–y
    grid.position.z = 0.5;
    this.ground.add(grid);
    const axes = new THREE.Group();
    const mat = (c) => new THREE.LineBasicMaterial({ color: c });
    const line = (a, b, c) => new THREE.Line(new THREE.BufferGeometry().setFromPoints([a, b]), mat(c));
    axes.add(line(new THREE.Vector3(0, 0, 1), new THREE.Vector3(400, 0, 1), 0xff7070)); // East
    axes.add(line(new THREE.Vector3(0, 0, 1), new THREE.Vector3(0, 400, 1), 0x70ff9a)); // North
    axes.add(line(new THREE.Vector3(0, 0, 1), new THREE.Vector3(0, 0, 400), 0x70a8ff)); // Up
    this.ground.add(axes);
    this.groundSize = size;
  }

  /** A text label that keeps its size on screen. */
  label(text, color) {
    const c = document.createElement("canvas");
    const ctx = c.getContext("2d");
    const font = "600 26px system-ui, sans-serif";
    ctx.font = font;
    const w = Math.ceil(ctx.measureText(text).width) + 16;
    c.width = w;
    c.height = 36;
    ctx.font = font;
    ctx.fillStyle = "rgba(12,18,25,0.78)";
    ctx.fillRect(0, 0, w, 36);
    ctx.fillStyle = color;
    ctx.textBaseline = "middle";
    ctx.fillText(text, 8, 19);
    const tex = new THREE.CanvasTexture(c);
    tex.colorSpace = THREE.SRGBColorSpace;
    const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: tex, sizeAttenuation: false, depthTest: false, transparent: true }));
    const h = 0.036;
    sprite.scale.set((h * w) / 36, h, 1);
    sprite.center.set(-0.08, -0.25);
    sprite.renderOrder = 10;
    sprite.userData.text = text;
    return sprite;
  }

  setLabel(o, text, color) {
    if (o.label && o.label.userData.text === text) return;
    if (o.label) {
      o.label.parent.remove(o.label);
      o.label.material.map.dispose();
      o.label.material.dispose();
    }
    o.label = this.label(text, color);
    this.scene.add(o.label);
  }

  trackObj(id) {
    let o = this.trackObjs.get(id);
    if (o) return o;
    const color = colorHex(id);
    const group = new THREE.Group();
    const ellipsoid = new THREE.Mesh(
      this.sphere,
      new THREE.MeshPhongMaterial({
        color,
        transparent: true,
        opacity: 0.32,
        depthWrite: false,
        side: THREE.DoubleSide,
        shininess: 40,
      }),
    );
    ellipsoid.matrixAutoUpdate = false;
    const marker = new THREE.Mesh(this.marker, new THREE.MeshPhongMaterial({ color, emissive: color, emissiveIntensity: 0.35 }));
    const bound = new THREE.Mesh(
      this.cylinder,
      new THREE.MeshBasicMaterial({ color: 0xffaa3c, transparent: true, opacity: 0.22, depthWrite: false, side: THREE.DoubleSide }),
    );
    bound.visible = false;
    const history = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color, transparent: true, opacity: 0.7 }));
    history.frustumCulled = false;
    group.add(ellipsoid, marker, bound, history);
    this.scene.add(group);
    o = { group, ellipsoid, marker, bound, history, historyLen: -1 };
    this.trackObjs.set(id, o);
    return o;
  }

  /** The instanced mesh of the UAVs' bodies, with room for `n` (grown by doubling). */
  uavCapacity(n) {
    if (this.uavBodies && this.uavBodies.instanceMatrix.count >= n) return this.uavBodies;
    const cap = Math.max(16, 2 ** Math.ceil(Math.log2(Math.max(n, 1))));
    if (this.uavBodies) {
      this.scene.remove(this.uavBodies);
      this.uavBodies.dispose();
    }
    this.uavBodies = new THREE.InstancedMesh(this.uavGeom, this.uavMaterial, cap);
    this.uavBodies.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    this.uavBodies.frustumCulled = false;
    this.uavBodies.count = 0;
    this.scene.add(this.uavBodies);
    return this.uavBodies;
  }

  truthObj(id) {
    let o = this.truthObjs.get(id);
    if (o) return o;
    const line = new THREE.Line(
      new THREE.BufferGeometry(),
      new THREE.LineBasicMaterial({ color: 0xeef2f6, transparent: true, opacity: 0.5 }),
    );
    line.frustumCulled = false;
    this.scene.add(line);
    o = { line, key: null };
    this.truthObjs.set(id, o);
    return o;
  }

  /** Updates the scene objects from the store (every frame, whether drawn or not). */
  update(now, layers) {
    if (!this.renderer) return;
    const s = this.store;
    const planeZ = s.planeZ;
    const st = { tracks: 0, ellipsoids: 0, bounds: 0, uavs: 0, rays: 0, standoff: 0, vectors: 0, frames: this.stats.frames };
    // Tracks.
    for (const [id, o] of this.trackObjs) {
      if (!s.tracks.has(id)) {
        this.scene.remove(o.group);
        o.history.geometry.dispose();
        if (o.label) {
          this.scene.remove(o.label);
          o.label.material.map.dispose();
          o.label.material.dispose();
        }
        this.trackObjs.delete(id);
      }
    }
    const m = new THREE.Matrix4();
    for (const k of s.tracks.values()) {
      const o = this.trackObj(k.id);
      const confirmed = k.view.status === "confirmed";
      const [x, y, z] = k.view.state;
      o.marker.position.set(x, y, z);
      o.confirmed = confirmed;
      o.marker.material.opacity = confirmed ? 1 : 0.5;
      o.marker.material.transparent = !confirmed;
      const ax = regionAxes(k.view);
      if (ax && layers.ellipses) {
        // The unit sphere's x, y, z go to the three axes (matrix columns), centred on the track.
        m.set(
          ax[0][0], ax[1][0], ax[2][0], x,
          ax[0][1], ax[1][1], ax[2][1], y,
          ax[0][2], ax[1][2], ax[2][2], z,
          0, 0, 0, 1,
        );
        o.ellipsoid.matrix.copy(m);
        o.ellipsoid.visible = true;
        o.ellipsoid.material.opacity = confirmed ? 0.34 : 0.12;
        if (confirmed) st.ellipsoids += 1;
      } else {
        o.ellipsoid.visible = false;
      }
      const b = k.bound;
      if (b && layers.bound && confirmed) {
        o.bound.visible = true;
        o.bound.position.set(b.center[0], b.center[1], z);
        o.bound.rotation.set(0, 0, b.angle_rad);
        o.bound.scale.set(b.semi_axes[0], b.semi_axes[1], 30);
        st.bounds += 1;
      } else {
        o.bound.visible = false;
      }
      o.history.visible = layers.history;
      const last = k.history[k.history.length - 1];
      if (layers.history && o.historyKey !== last) {
        setLine(o.history, k.history, 2);
        o.historyKey = last;
      }
      if (confirmed) {
        st.tracks += 1;
        this.setLabel(o, `T${k.id}`, `#${colorHex(k.id).toString(16).padStart(6, "0")}`);
        o.label.position.set(x, y, z);
      }
      if (o.label) o.label.visible = confirmed;
    }
    // UAVs.
    const shown = [...s.vehicles.values()].filter((v) => v.position);
    const bodies = this.uavCapacity(shown.length);
    const swarm = shown.length > LABELLED_UAVS;
    const labelled = new Set();
    const color = new THREE.Color();
    let trailsChanged = shown.length !== this.trailKeys.size;
    this.uavPlaced.length = shown.length;
    shown.forEach((v, i) => {
      const [x, y, z] = v.position;
      this.uavPlaced[i] = [x, y, z, v.heading ?? 0];
      const lost = v.link && v.link.state === "lost";
      bodies.setColorAt(i, color.setHex(lost ? 0xff5d5d : 0xf4f7fb));
      if (!swarm || lost) {
        let o = this.uavLabels.get(v.label);
        if (!o) this.uavLabels.set(v.label, (o = {}));
        this.setLabel(o, `UAV ${v.label} · ${(z - planeZ).toFixed(0)} m${lost ? " · LINK LOST" : ""}`, lost ? "#ff5d5d" : "#f4f7fb");
        o.label.position.set(x, y, z);
        labelled.add(v.label);
      }
      const lastTrail = v.trail[v.trail.length - 1];
      if (this.trailKeys.get(v.label) !== lastTrail) trailsChanged = true;
      st.uavs += 1;
    });
    bodies.count = shown.length;
    if (bodies.instanceColor) bodies.instanceColor.needsUpdate = true;
    this.placeUavs();
    for (const [label, o] of this.uavLabels) {
      if (labelled.has(label)) continue;
      this.scene.remove(o.label);
      o.label.material.map.dispose();
      o.label.material.dispose();
      this.uavLabels.delete(label);
    }
    // Drop lines: written in place; their dashes run down from the UAV.
    const dropPos = growAttribute(this.drops, "position", 3, 2 * shown.length);
    const dropDist = growAttribute(this.drops, "lineDistance", 1, 2 * shown.length);
    shown.forEach((v, i) => {
      const [x, y, z] = v.position;
      dropPos.setXYZ(2 * i, x, y, z);
      dropPos.setXYZ(2 * i + 1, x, y, planeZ);
      dropDist.setX(2 * i, 0);
      dropDist.setX(2 * i + 1, Math.abs(z - planeZ));
    });
    dropPos.needsUpdate = true;
    dropDist.needsUpdate = true;
    this.drops.geometry.setDrawRange(0, 2 * shown.length);
    // Trails: rewritten at most TRAIL_HZ times a second (a swarm's: their newest points).
    this.trails.visible = layers.trails;
    if (layers.trails && trailsChanged && now - (this.trailsAt ?? -Infinity) >= 1000 / TRAIL_HZ) {
      this.trailsAt = now;
      const keep = swarm ? SWARM_TRAIL : Infinity;
      let segments = 0;
      for (const v of shown) segments += Math.max(0, Math.min(v.trail.length, keep) - 1);
      const pos = growAttribute(this.trails, "position", 3, 2 * segments);
      let j = 0;
      this.trailKeys.clear();
      for (const v of shown) {
        const t = v.trail;
        for (let i = Math.max(1, t.length - keep + 1); i < t.length; i++) {
          pos.setXYZ(j++, t[i - 1][1], t[i - 1][2], t[i - 1][3]);
          pos.setXYZ(j++, t[i][1], t[i][2], t[i][3]);
        }
        this.trailKeys.set(v.label, t[t.length - 1]);
      }
      pos.needsUpdate = true;
      this.trails.geometry.setDrawRange(0, j);
    }
    // Standoff rings and commanded velocities of the active assignments.
    const active = new Set();
    let nc = 0;
    const cpos = this.cmds.geometry.attributes.position;
    for (const a of layers.standoff === false ? [] : s.assignments.values()) {
      if (a.state !== "active") continue;
      const k = s.tracks.get(a.track);
      if (k && Number.isFinite(a.radius_m)) {
        let ring = this.rings.get(a.id);
        if (!ring) {
          ring = new THREE.LineLoop(this.ringGeom, new THREE.LineDashedMaterial({ color: 0x78dcff, dashSize: 0.06, gapSize: 0.04, transparent: true, opacity: 0.85 }));
          ring.computeLineDistances();
          this.scene.add(ring);
          this.rings.set(a.id, ring);
        }
        ring.position.set(k.view.state[0], k.view.state[1], (k.view.state[2] || planeZ) + a.height_m);
        ring.scale.set(a.radius_m, a.radius_m, 1);
        active.add(a.id);
        st.standoff += 1;
      }
      for (const slot of a.vehicles || []) {
        const v = s.vehicles.get(String(slot.vehicle));
        const u = slot.commanded_velocity;
        if (!v || !v.position || !u || slot.state !== "offboard" || nc >= MAX_CMDS) continue;
        const [x, y, z] = v.position;
        cpos.setXYZ(2 * nc, x, y, z);
        cpos.setXYZ(2 * nc + 1, x + 10 * u[0], y + 10 * u[1], z + 10 * (u[2] || 0));
        nc += 1;
      }
    }
    for (const [id, ring] of this.rings) {
      if (!active.has(id)) {
        this.scene.remove(ring);
        ring.material.dispose();
        this.rings.delete(id);
      }
    }
    if (nc || this.cmds.geometry.drawRange.count) cpos.needsUpdate = true;
    this.cmds.geometry.setDrawRange(0, 2 * nc);
    st.vectors = nc;
    // Truth.
    for (const t of s.truth.values()) {
      const o = this.truthObj(t.id);
      o.line.visible = layers.truth;
      const lastTruth = t.samples[t.samples.length - 1];
      if (layers.truth && o.key !== lastTruth) {
        setLine(o.line, t.samples, 1);
        o.key = lastTruth;
      }
    }
    // Camera rays: UAV → detection (fading).
    const pos = this.rays.geometry.attributes.position;
    const col = this.rays.geometry.attributes.color;
    let n = 0;
    if (layers.detections) {
      for (let i = s.detections.length - 1; i >= 0 && n < MAX_RAYS; i--) {
        const d = s.detections[i];
        const a = Store.fade(d, now);
        if (a <= 0) continue;
        const ray = detectionRay(d.kind, d.z, d.platform, planeZ);
        const end = ray ? ray[1] : detectionPoint(d.kind, d.z, d.platform, planeZ);
        if (!end) continue;
        pos.setXYZ(2 * n, d.platform[0], d.platform[1], d.platform[2]);
        pos.setXYZ(2 * n + 1, end[0], end[1], end[2]);
        col.setXYZW(2 * n, 1.0, 0.77, 0.35, 0.05 * a);
        col.setXYZW(2 * n + 1, 1.0, 0.77, 0.35, 0.7 * a);
        n++;
      }
    }
    this.rays.geometry.setDrawRange(0, 2 * n);
    pos.needsUpdate = true;
    col.needsUpdate = true;
    st.rays = n;
    this.stats = st;
  }

  /** Frames the vehicles and tracks (until the operator moves the camera). */
  autoFrame() {
    const pts = [];
    for (const v of this.store.vehicles.values()) if (v.position) pts.push(v.position);
    for (const k of this.store.tracks.values()) pts.push(k.view.state);
    if (!pts.length) return;
    const box = new THREE.Box3();
    for (const p of pts) box.expandByPoint(new THREE.Vector3(p[0], p[1], p[2]));
    box.expandByPoint(new THREE.Vector3(box.min.x, box.min.y, this.store.planeZ));
    const c = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3());
    const r = Math.max(size.x, size.y, 800) * 0.58;
    this.controls.target.set(c.x, c.y, this.store.planeZ + 0.35 * (box.max.z - this.store.planeZ));
    const dir = new THREE.Vector3(-0.45, -0.85, 0.62).normalize();
    this.camera.position.copy(this.controls.target).addScaledVector(dir, (1.25 * r) / Math.tan((this.camera.fov * Math.PI) / 360));
    const span = Math.max(size.x, size.y) + 4000;
    const grid = Math.max(4000, Math.ceil(span / 1000) * 1000);
    if (grid !== this.groundSize) this.buildGround(grid, grid > 12000 ? 500 : 250);
    this.ground.position.set(Math.round(c.x / 1000) * 1000, Math.round(c.y / 1000) * 1000, this.store.planeZ);
  }

  /**
   * Sets every UAV body's instance matrix: its position, its heading (clockwise from North) and a
   * scale that keeps it legible on screen whatever the zoom (`uavScale`, set by `render`).
   */
  placeUavs() {
    const bodies = this.uavBodies;
    if (!bodies) return;
    const m = new THREE.Matrix4();
    const q = new THREE.Quaternion();
    const p = new THREE.Vector3();
    const sc = new THREE.Vector3();
    const zAxis = new THREE.Vector3(0, 0, 1);
    const k = this.uavScale ?? 0;
    this.uavPlaced.forEach(([x, y, z, heading], i) => {
      p.set(x, y, z);
      q.setFromAxisAngle(zAxis, -heading);
      const f = k ? Math.max(0.5, (this.camera.position.distanceTo(p) * k * 1.4) / 16) : 1;
      m.compose(p, q, sc.set(f, f, f));
      bodies.setMatrixAt(i, m);
    });
    bodies.instanceMatrix.needsUpdate = true;
  }

  /** Renders when the camera moved or (at most DATA_FPS times a second) the data changed. */
  render(now = performance.now()) {
    if (!this.renderer) return false;
    const [w, h] = cssSize(this.canvas);
    if (!w || !h) return;
    const dpr = Math.round(Math.min(window.devicePixelRatio || 1, 2) * this.quality * 20) / 20;
    const size = this.renderer.getSize(new THREE.Vector2());
    if (size.x !== w || size.y !== h || this.renderer.getPixelRatio() !== dpr) {
      this.cameraMoved = true;
      this.renderer.setPixelRatio(dpr);
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / h;
      this.camera.updateProjectionMatrix();
    }
    if (!this.userMoved && (this.stats.frames % 30 === 0 || !this.framed)) {
      this.autoFrame();
      this.framed = true;
      this.cameraMoved = true;
    }
    this.controls.update(); // damping: emits "change" while the camera glides
    const dataChanged = this.dataVersion !== this.store.version || this.store.detections.length > 0;
    const due = now - this.lastRender >= 1000 / this.dataFps;
    if (!(this.cameraMoved || (dataChanged && due) || now - this.lastRender > 1000)) return false;
    // Markers and UAVs keep a legible size on screen, whatever the zoom.
    const k = Math.tan((this.camera.fov * Math.PI) / 360) / 40;
    this.uavScale = k;
    this.placeUavs();
    for (const o of this.trackObjs.values()) {
      const f = this.camera.position.distanceTo(o.marker.position) * k * 0.5 / 9;
      o.marker.scale.setScalar(Math.max(0.3, f) * (o.confirmed ? 1 : 0.6));
    }
    this.renderer.render(this.scene, this.camera);
    this.cameraMoved = false;
    this.dataVersion = this.store.version;
    this.lastRender = now;
    this.stats.frames += 1;
    this.renders += 1;
    return true;
  }

  /**
   * Keeps the page smooth where WebGL is slow (software rendering): below 30 fps the 3-D view
   * renders fewer pixels and fewer data updates; above 42 fps it goes back towards full quality.
   */
  adapt(fps) {
    if (!this.renderer) return;
    this.adaptCalls = (this.adaptCalls || 0) + 1;
    if (this.adaptCalls <= 3) return; // start-up (module and shader compilation) is not the steady state
    if (fps < 30) {
      this.quality = Math.max(0.4, this.quality * 0.8);
      this.dataFps = Math.max(2, this.dataFps * 0.7);
    } else if (fps > 42) {
      this.quality = Math.min(1, this.quality * 1.15);
      this.dataFps = Math.min(DATA_FPS, this.dataFps * 1.3);
    }
  }

  resetView() {
    this.userMoved = false;
    this.autoFrame();
    this.cameraMoved = true;
  }
}
