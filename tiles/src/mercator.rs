//! Web Mercator (EPSG:3857) tile arithmetic: the XYZ scheme of OpenStreetMap, Leaflet and
//! MapLibre (tile `x` from the antimeridian eastwards, `y` from the north down), and the TMS row
//! of MBTiles (`tile_row = 2^z − 1 − y`, counted from the south).

use std::f64::consts::PI;

/// Edge of a tile (px).
pub const TILE_SIZE: u32 = 256;

/// Largest latitude Web Mercator shows (°): the square world's edge.
pub const MAX_LAT_DEG: f64 = 85.051_128_779_806_59;

/// WGS-84 semi-major axis (m): the sphere Web Mercator projects onto.
const EARTH_RADIUS_M: f64 = 6_378_137.0;

/// A rectangle of longitude and latitude (°), as MBTiles' `bounds`: west, south, east, north.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Western longitude (°).
    pub west: f64,
    /// Southern latitude (°).
    pub south: f64,
    /// Eastern longitude (°).
    pub east: f64,
    /// Northern latitude (°).
    pub north: f64,
}

impl Bounds {
    /// Parses MBTiles' `bounds` value, `"W,S,E,N"`; `None` unless four finite numbers with
    /// W < E and S < N within the Mercator square.
    pub fn parse(s: &str) -> Option<Self> {
        let v: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>().ok())
            .collect::<Option<_>>()?;
        let [west, south, east, north] = v[..] else {
            return None;
        };
        let b = Self {
            west,
            south,
            east,
            north,
        };
        b.is_valid().then_some(b)
    }

    /// Finite, ordered and on the map.
    pub fn is_valid(&self) -> bool {
        [self.west, self.south, self.east, self.north]
            .iter()
            .all(|v| v.is_finite())
            && self.west < self.east
            && self.south < self.north
            && self.west >= -180.0
            && self.east <= 180.0
            && self.south >= -90.0
            && self.north <= 90.0
    }

    /// MBTiles' text form, `"W,S,E,N"`.
    pub fn to_metadata(&self) -> String {
        format!(
            "{:.7},{:.7},{:.7},{:.7}",
            self.west, self.south, self.east, self.north
        )
    }

    /// The tiles of zoom `z` this rectangle touches: inclusive column and row ranges (XYZ).
    pub fn tile_range(&self, z: u8) -> TileRange {
        let n = tiles_at(z);
        let last = n - 1;
        let col = |lon: f64| ((world_x(lon) * n as f64).floor().max(0.0) as u32).min(last);
        let row = |lat: f64| ((world_y(lat) * n as f64).floor().max(0.0) as u32).min(last);
        TileRange {
            z,
            x: col(self.west)..=col(self.east),
            y: row(self.north)..=row(self.south),
        }
    }
}

/// The tiles of one zoom level inside a rectangle (XYZ).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TileRange {
    /// Zoom level.
    pub z: u8,
    /// Columns.
    pub x: std::ops::RangeInclusive<u32>,
    /// Rows, from the north.
    pub y: std::ops::RangeInclusive<u32>,
}

impl TileRange {
    /// How many tiles.
    pub fn len(&self) -> u64 {
        let n = |r: &std::ops::RangeInclusive<u32>| u64::from(r.end() - r.start() + 1);
        n(&self.x) * n(&self.y)
    }

    /// Never empty (a rectangle touches at least one tile); for clippy's `len` rule.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Every tile, row by row.
    pub fn iter(&self) -> impl Iterator<Item = TileId> + '_ {
        self.y
            .clone()
            .flat_map(move |y| self.x.clone().map(move |x| TileId { z: self.z, x, y }))
    }
}

/// One tile of the XYZ scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TileId {
    /// Zoom level.
    pub z: u8,
    /// Column, from the antimeridian eastwards.
    pub x: u32,
    /// Row, from the north.
    pub y: u32,
}

impl TileId {
    /// The tile, if `x` and `y` are on the map at zoom `z` (`z` ≤ [`MAX_ZOOM`]).
    pub fn new(z: u8, x: u32, y: u32) -> Option<Self> {
        (z <= MAX_ZOOM && x < tiles_at(z) && y < tiles_at(z)).then_some(Self { z, x, y })
    }

    /// Its MBTiles (TMS) row: `2^z − 1 − y`.
    pub fn tms_row(&self) -> u32 {
        tiles_at(self.z) - 1 - self.y
    }

    /// Global pixel (at this zoom) of its north-west corner.
    pub fn origin_px(&self) -> (f64, f64) {
        (
            f64::from(self.x) * f64::from(TILE_SIZE),
            f64::from(self.y) * f64::from(TILE_SIZE),
        )
    }
}

/// Deepest zoom level the tile arithmetic takes (2³⁰ tiles a side still fit a `u32`).
pub const MAX_ZOOM: u8 = 30;

/// Tiles a side at zoom `z`.
pub fn tiles_at(z: u8) -> u32 {
    1u32 << z.min(MAX_ZOOM)
}

/// Longitude as a fraction of the world's width, from the antimeridian.
fn world_x(lon_deg: f64) -> f64 {
    (lon_deg + 180.0) / 360.0
}

/// Latitude as a fraction of the world's height, from the north (clamped to the square).
fn world_y(lat_deg: f64) -> f64 {
    let lat = lat_deg.clamp(-MAX_LAT_DEG, MAX_LAT_DEG).to_radians();
    (1.0 - (lat.tan() + 1.0 / lat.cos()).ln() / PI) / 2.0
}

/// Global pixel coordinates (x east, y south, at zoom `z`) of a longitude and latitude.
pub fn to_pixel(lon_deg: f64, lat_deg: f64, z: u8) -> (f64, f64) {
    let size = world_px(z);
    (world_x(lon_deg) * size, world_y(lat_deg) * size)
}

/// The longitude and latitude (°) of global pixel coordinates at zoom `z`.
pub fn from_pixel(x: f64, y: f64, z: u8) -> (f64, f64) {
    let size = world_px(z);
    let lon = x / size * 360.0 - 180.0;
    let lat = (PI * (1.0 - 2.0 * y / size)).sinh().atan().to_degrees();
    (lon, lat)
}

/// The world's width in pixels at zoom `z`.
pub fn world_px(z: u8) -> f64 {
    f64::from(TILE_SIZE) * f64::from(tiles_at(z))
}

/// Pixels per metre on the ground at latitude `lat_deg` and zoom `z`.
pub fn px_per_m(lat_deg: f64, z: u8) -> f64 {
    world_px(z) / (2.0 * PI * EARTH_RADIUS_M * lat_deg.to_radians().cos())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_and_degrees_round_trip_and_match_the_osm_tile_of_zurich() {
        // PX4 SITL's home: tile 15/17161/11472 in OpenStreetMap's scheme (x = (lon + 180) / 360
        // · 2^z, y = (1 − asinh(tan lat) / π) / 2 · 2^z).
        let (x, y) = to_pixel(8.545_594, 47.397_742, 15);
        assert_eq!(((x / 256.0) as u32, (y / 256.0) as u32), (17_161, 11_472));
        let (lon, lat) = from_pixel(x, y, 15);
        assert!((lon - 8.545_594).abs() < 1e-9 && (lat - 47.397_742).abs() < 1e-9);
        let t = TileId::new(15, 17_161, 11_472).expect("on the map");
        assert_eq!(t.tms_row(), (1 << 15) - 1 - 11_472);
        assert_eq!(TileId::new(2, 4, 0), None);
        assert_eq!(TileId::new(31, 0, 0), None);
    }

    #[test]
    fn a_rectangle_covers_the_tiles_it_touches() {
        let b = Bounds::parse("8.5, 47.38, 8.6, 47.42").expect("bounds");
        let r = b.tile_range(15);
        let (x0, y0) = to_pixel(8.5, 47.42, 15);
        let (x1, y1) = to_pixel(8.6, 47.38, 15);
        assert_eq!(*r.x.start(), (x0 / 256.0) as u32);
        assert_eq!(*r.x.end(), (x1 / 256.0) as u32);
        assert_eq!(*r.y.start(), (y0 / 256.0) as u32);
        assert_eq!(*r.y.end(), (y1 / 256.0) as u32);
        assert_eq!(r.iter().count() as u64, r.len());
        assert_eq!(b.to_metadata(), "8.5000000,47.3800000,8.6000000,47.4200000");
        for bad in ["1,2,3", "8.6,47,8.5,48", "a,b,c,d", "0,0,181,1"] {
            assert_eq!(Bounds::parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn the_ground_scale_is_the_cosine_of_the_latitude() {
        // 156 543 m per pixel at the equator at zoom 0.
        assert!((1.0 / px_per_m(0.0, 0) - 156_543.03).abs() < 0.01);
        assert!((px_per_m(60.0, 10) / px_per_m(0.0, 10) - 2.0).abs() < 1e-12);
    }
}
