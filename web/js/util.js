// Small helpers: covariance geometry, colours, formatting. No DOM, no state.

/** χ² quantiles of 0.95 for 2 and 3 degrees of freedom (as the server's `ellipse_95`). */
export const CHI2_95_2 = 5.991464547107979;
export const CHI2_95_3 = 7.814727903251178;

/** The position block of a TrackView's covariance over state indices `dims` (null if absent). */
export function positionCov(track, dims) {
  const at = dims.map((d) => track.cov_dims.indexOf(d));
  if (at.some((i) => i < 0)) return null;
  return at.map((i) => at.map((j) => track.cov[i][j]));
}

/** Semi-axes and angle (rad, counter-clockwise from East) of the ellipse {x: xᵀ (kP)⁻¹ x ≤ 1}. */
export function ellipseOf(p, k = CHI2_95_2) {
  const [a, b, c] = [p[0][0], 0.5 * (p[0][1] + p[1][0]), p[1][1]];
  const mean = 0.5 * (a + c);
  const diff = Math.hypot(0.5 * (a - c), b);
  const l1 = Math.max(mean + diff, 0);
  const l2 = Math.max(mean - diff, 0);
  const angle = 0.5 * Math.atan2(2 * b, a - c);
  const out = { a: Math.sqrt(k * l1), b: Math.sqrt(k * l2), angle };
  return Number.isFinite(out.a) && Number.isFinite(out.b) && Number.isFinite(angle) ? out : null;
}

/** The 95 % ellipse of a track's (x, y), or null. */
export function trackEllipse(track) {
  const p = positionCov(track, [0, 1]);
  return p ? ellipseOf(p) : null;
}

/**
 * The 3 × 3 position covariance of a track; planar tracks (no z) get `zVar` on z so that their
 * ellipsoid is drawn as a thin disc.
 */
export function positionCov3(track, zVar = 1.0) {
  const p3 = positionCov(track, [0, 1, 2]);
  if (p3) return p3;
  const p2 = positionCov(track, [0, 1]);
  if (!p2) return null;
  return [
    [p2[0][0], p2[0][1], 0],
    [p2[1][0], p2[1][1], 0],
    [0, 0, zVar],
  ];
}

/** Lower Cholesky factor of a symmetric 3 × 3 matrix (null when not positive definite). */
export function cholesky3(p) {
  const l = [
    [0, 0, 0],
    [0, 0, 0],
    [0, 0, 0],
  ];
  for (let i = 0; i < 3; i++) {
    for (let j = 0; j <= i; j++) {
      let s = 0.5 * (p[i][j] + p[j][i]);
      for (let k = 0; k < j; k++) s -= l[i][k] * l[j][k];
      if (i === j) {
        if (!(s > 0)) return null;
        l[i][i] = Math.sqrt(s);
      } else {
        l[i][j] = s / l[j][j];
      }
    }
  }
  return l;
}

/** dᵀ P⁻¹ d for a 2 × 2 or 3 × 3 P (NaN when singular). */
export function mahalanobis2(d, p) {
  if (d.length === 2) {
    const det = p[0][0] * p[1][1] - p[0][1] * p[1][0];
    if (!(Math.abs(det) > 0)) return NaN;
    return (p[1][1] * d[0] * d[0] - (p[0][1] + p[1][0]) * d[0] * d[1] + p[0][0] * d[1] * d[1]) / det;
  }
  const l = cholesky3(p);
  if (!l) return NaN;
  // Solve L y = d; the result is |y|².
  const y0 = d[0] / l[0][0];
  const y1 = (d[1] - l[1][0] * y0) / l[1][1];
  const y2 = (d[2] - l[2][0] * y0 - l[2][1] * y1) / l[2][2];
  return y0 * y0 + y1 * y1 + y2 * y2;
}

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
