// Small helpers: colours, formatting, where to draw a detection. No DOM, no state, no estimation
// math: the server sends each track's 95 % ellipse and ellipsoid (`TrackDto`).

/** A distinct, legible colour per integer id (golden-angle hues). */
export function colorFor(id, sat = 72, light = 62) {
  const h = (Number(id) * 137.508 + 190) % 360;
  return `hsl(${h.toFixed(1)}, ${sat}%, ${light}%)`;
}

/** The same hue as an RGB number for three.js. */
export function colorHex(id, sat = 0.72, light = 0.62) {
  const h = ((Number(id) * 137.508 + 190) % 360) / 360;
  const q = light < 0.5 ? light * (1 + sat) : light + sat - light * sat;
  const p = 2 * light - q;
  const f = (t) => {
    t = (t + 1) % 1;
    if (t < 1 / 6) return p + (q - p) * 6 * t;
    if (t < 1 / 2) return q;
    if (t < 2 / 3) return p + (q - p) * (2 / 3 - t) * 6;
    return p;
  };
  return (Math.round(f(h + 1 / 3) * 255) << 16) | (Math.round(f(h) * 255) << 8) | Math.round(f(h - 1 / 3) * 255);
}

/**
 * Beyond this many UAVs the map and the 3-D view draw a swarm: every UAV's body, trail and drop
 * line in one batch, and a label only on the UAVs whose link is lost (255 labels are unreadable
 * and cost more than the rest of the frame).
 */
export const LABELLED_UAVS = 24;

/** The points of a UAV's trail drawn in a swarm (its newest ones; 300 are kept). */
export const SWARM_TRAIL = 30;

/** A number with `d` decimals, or an en dash. */
export function fmt(v, d = 1) {
  return Number.isFinite(v) ? v.toFixed(d) : "–";
}

/** A distance in m or km. */
export function fmtDist(m) {
  if (!Number.isFinite(m)) return "–";
  const a = Math.abs(m);
  if (a >= 1000) return `${(m / 1000).toFixed(a >= 10000 ? 0 : 1)} km`;
  return `${m.toFixed(a >= 10 ? 0 : 1)} m`;
}

/** The largest of 1, 2, 5 × 10ⁿ not above `x`. */
export function niceStep(x) {
  const e = Math.pow(10, Math.floor(Math.log10(x)));
  const f = x / e;
  return (f >= 5 ? 5 : f >= 2 ? 2 : 1) * e;
}

/** Position of a detection on the ground/world for drawing: null for angle-only detections. */
export function detectionPoint(kind, z, platform, planeZ = 0) {
  switch (kind) {
    case "position":
      return [z[0], z[1], z.length > 2 ? z[2] : planeZ];
    case "range_bearing": {
      // Range is 3-D Euclidean; the target is assumed on the ground plane for display.
      const dz = platform[2] - planeZ;
      const h = Math.sqrt(Math.max(z[0] * z[0] - dz * dz, 0));
      return [platform[0] + h * Math.sin(z[1]), platform[1] + h * Math.cos(z[1]), planeZ];
    }
    default:
      return null;
  }
}

/**
 * The line of sight of an angle-only detection (`az_el`, `bearing_size`: azimuth clockwise from
 * North, elevation up), from the platform to where it meets the ground plane, else `maxRange` m
 * long. Null for other kinds.
 */
export function detectionRay(kind, z, platform, planeZ = 0, maxRange = 3000) {
  if (kind !== "az_el" && kind !== "bearing_size") return null;
  const [az, el] = z;
  const dir = [Math.sin(az) * Math.cos(el), Math.cos(az) * Math.cos(el), Math.sin(el)];
  let len = maxRange;
  if (dir[2] < -1e-6) len = Math.min(maxRange * 3, (platform[2] - planeZ) / -dir[2]);
  return [platform, [platform[0] + len * dir[0], platform[1] + len * dir[1], platform[2] + len * dir[2]]];
}

/** The CSS size of each element drawn into, kept by a ResizeObserver ([width, height], px). */
const canvasSizes = new WeakMap();
const sizeWatch = new ResizeObserver((entries) => {
  for (const e of entries) canvasSizes.set(e.target, [e.contentRect.width, e.contentRect.height]);
});

/**
 * The CSS size [width, height] of element `c` without a layout: reading `clientWidth` after the
 * panels changed the page forces one, on every frame; with a swarm's lists (255 vehicles, 100
 * tracks) that cost more than the drawing (BENCHMARKS "The page with a swarm").
 */
export function cssSize(c) {
  let s = canvasSizes.get(c);
  if (!s) {
    s = [c.clientWidth, c.clientHeight];
    canvasSizes.set(c, s);
    sizeWatch.observe(c);
  }
  return s;
}
