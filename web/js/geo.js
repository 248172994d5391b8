// WGS-84 geodesy for the geographic map: the server's local East-North-Up frame (its origin from
// GET /api/v1/map) to and from latitude, longitude and height, through Earth-centred
// Earth-fixed coordinates — the same conversion as harrier-link's `geo` (Bowring's initial
// latitude, then fixed-point refinement), exact far from the origin.

const A = 6378137.0; // WGS-84 semi-major axis (m)
const F = 1 / 298.257223563; // flattening
const E2 = F * (2 - F);
const B = A * (1 - F);
const EP2 = E2 / (1 - E2);
const RAD = Math.PI / 180;

/** ECEF (m) of a latitude, longitude (°) and height (m). */
export function toEcef(lat, lon, h) {
  const [sl, cl] = [Math.sin(lat * RAD), Math.cos(lat * RAD)];
  const n = A / Math.sqrt(1 - E2 * sl * sl);
  const r = (n + h) * cl;
  return [r * Math.cos(lon * RAD), r * Math.sin(lon * RAD), (n * (1 - E2) + h) * sl];
}

/** Latitude, longitude (°) and height (m) of ECEF coordinates (m). */
export function fromEcef(x, y, z) {
  const lon = Math.atan2(y, x);
  const rho = Math.hypot(x, y);
  const theta = Math.atan2(z * A, rho * B);
  let lat = Math.atan2(z + EP2 * B * Math.sin(theta) ** 3, rho - E2 * A * Math.cos(theta) ** 3);
  let h = 0;
  for (let i = 0; i < 2; i += 1) {
    const s = Math.sin(lat);
    const n = A / Math.sqrt(1 - E2 * s * s);
    h = Math.abs(Math.cos(lat)) > 1e-9 ? rho / Math.cos(lat) - n : Math.abs(z) - B;
    lat = Math.atan2(z, rho * (1 - (E2 * n) / (n + h)));
  }
  return [lat / RAD, lon / RAD, h];
}

/** The local ENU tangent plane at a WGS-84 origin ({lat_deg, lon_deg, alt_m}). */
export class EnuFrame {
  constructor(origin) {
    this.origin = origin;
    const [lat, lon] = [origin.lat_deg * RAD, origin.lon_deg * RAD];
    this.o = toEcef(origin.lat_deg, origin.lon_deg, origin.alt_m);
    const [sl, cl, so, co] = [Math.sin(lat), Math.cos(lat), Math.sin(lon), Math.cos(lon)];
    // Rows: east, north, up in ECEF.
    this.e = [-so, co, 0];
    this.n = [-sl * co, -sl * so, cl];
    this.u = [cl * co, cl * so, sl];
  }

  /** [lat, lon, h] of ENU (m). */
  toGeodetic(x, y, z = 0) {
    const { e, n, u, o } = this;
    return fromEcef(o[0] + x * e[0] + y * n[0] + z * u[0], o[1] + x * e[1] + y * n[1] + z * u[1], o[2] + x * e[2] + y * n[2] + z * u[2]);
  }

  /** ENU [x, y, z] (m) of a latitude, longitude (°) and height (m). */
  toEnu(lat, lon, h = this.origin.alt_m) {
    const p = toEcef(lat, lon, h);
    const d = [p[0] - this.o[0], p[1] - this.o[1], p[2] - this.o[2]];
    const dot = (a) => a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
    return [dot(this.e), dot(this.n), dot(this.u)];
  }
}

/** Ground metres per CSS pixel of a Web Mercator map at latitude `lat` (°) and zoom `zoom`. */
export function metresPerPixel(lat, zoom) {
  return (2 * Math.PI * A * Math.cos(lat * RAD)) / (256 * 2 ** zoom);
}
