//! One raster tile of a [`TileWorld`]: the ground, the roads (a dark casing under a light band
//! of the road's width, at least 1.5 px), the areas (red hatched discs), the names; PNG (RGB).
//! [`Scene`] holds the world in global pixels of one zoom level, computed once per level.

use std::f64::consts::PI;

use tiny_skia::{
    FillRule, LineCap, LineJoin, Mask, Paint, Path, PathBuilder, Pixmap, Stroke, Transform,
};

use super::text::{Size2, label};
use super::{TileWorld, ground};
use crate::mercator::{self, TILE_SIZE, TileId};

const ROAD_CASING: [u8; 4] = [24, 28, 24, 255];
const ROAD: [u8; 4] = [182, 178, 160, 255];
const AREA: [u8; 3] = [226, 70, 64];

/// Road names and area names are drawn from this zoom level on.
const NAMES_FROM_ZOOM: u8 = 15;

/// A road in global pixels.
#[derive(Debug)]
struct RoadPx {
    name: String,
    width_px: f64,
    points: Vec<(f64, f64)>,
    /// West, north, east, south (px), widened by half the casing.
    bbox: [f64; 4],
    /// Where its name goes: the middle point of the line.
    name_at: (f64, f64),
}

/// An area in global pixels.
#[derive(Debug)]
struct AreaPx {
    name: String,
    center: (f64, f64),
    radius_px: f64,
}

/// A world in the global pixels of one zoom level.
#[derive(Debug)]
pub(super) struct Scene {
    z: u8,
    roads: Vec<RoadPx>,
    areas: Vec<AreaPx>,
    title: (String, (f64, f64)),
    /// Ground metres per global pixel, and the scale of the plane the ground is laid on.
    m_per_px: f64,
    plane_scale: f64,
}

impl Scene {
    /// `world` at zoom `z`.
    pub(super) fn new(world: &TileWorld, z: u8) -> Self {
        let lat0 = world.center.lat;
        let px_per_m = mercator::px_per_m(lat0, z);
        let px = |p: super::LonLat| mercator::to_pixel(p.lon, p.lat, z);
        let roads = world
            .roads
            .iter()
            .filter(|r| r.points.len() >= 2)
            .map(|r| {
                let points: Vec<(f64, f64)> = r.points.iter().map(|&p| px(p)).collect();
                let width_px = (r.width_m * px_per_m).max(1.5);
                let pad = width_px / 2.0 + 2.0;
                let bbox = points.iter().fold(
                    [
                        f64::INFINITY,
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        f64::NEG_INFINITY,
                    ],
                    |b, &(x, y)| {
                        [
                            b[0].min(x - pad),
                            b[1].min(y - pad),
                            b[2].max(x + pad),
                            b[3].max(y + pad),
                        ]
                    },
                );
                RoadPx {
                    name: r.name.clone(),
                    width_px,
                    name_at: points[points.len() / 2],
                    points,
                    bbox,
                }
            })
            .collect();
        let areas = world
            .areas
            .iter()
            .map(|a| AreaPx {
                name: a.name.clone(),
                center: px(a.center),
                radius_px: (a.radius_m * px_per_m).max(3.0),
            })
            .collect();
        Self {
            z,
            roads,
            areas,
            title: (world.name.clone(), px(world.center)),
            m_per_px: 1.0 / px_per_m,
            plane_scale: lat0.to_radians().cos(),
        }
    }

    /// The tile `id` (at this scene's zoom) as a PNG.
    pub(super) fn tile(&self, id: TileId) -> Result<Vec<u8>, String> {
        debug_assert_eq!(id.z, self.z);
        let size = TILE_SIZE;
        let mut pixmap = Pixmap::new(size, size).ok_or("no pixmap")?;
        let (ox, oy) = id.origin_px();
        self.ground(&mut pixmap, ox, oy);
        let tile = [ox, oy, ox + f64::from(size), oy + f64::from(size)];
        for road in &self.roads {
            let b = road.bbox;
            if b[0] > tile[2] || b[2] < tile[0] || b[1] > tile[3] || b[3] < tile[1] {
                continue;
            }
            draw_road(&mut pixmap, road, ox, oy);
        }
        for area in &self.areas {
            let (cx, cy) = (area.center.0 - ox, area.center.1 - oy);
            let r = area.radius_px;
            let s = f64::from(size);
            if cx + r < -2.0 || cy + r < -2.0 || cx - r > s + 2.0 || cy - r > s + 2.0 {
                continue;
            }
            draw_area(&mut pixmap, cx, cy, r);
        }
        if self.z >= NAMES_FROM_ZOOM {
            for road in self.roads.iter().filter(|r| !r.name.is_empty()) {
                let (x, y) = road.name_at;
                label(
                    &mut pixmap,
                    &road.name,
                    x - ox,
                    y - oy - road.width_px - 10.0,
                    Size2::Name,
                );
            }
            for area in self.areas.iter().filter(|a| !a.name.is_empty()) {
                let (x, y) = area.center;
                label(&mut pixmap, &area.name, x - ox, y - oy, Size2::Name);
            }
        }
        let (title, (x, y)) = &self.title;
        if !title.is_empty() {
            label(&mut pixmap, title, x - ox, y - oy - 28.0, Size2::Title);
        }
        encode(&pixmap)
    }

    /// Fills the pixmap with the ground under it. The woods' noise is smooth: it is computed on a
    /// lattice of pixels [`ground::WOOD_SPACING_M`] apart and interpolated in between.
    fn ground(&self, pixmap: &mut Pixmap, ox: f64, oy: f64) {
        let w = pixmap.width() as usize;
        let world = mercator::world_px(self.z);
        // Web Mercator metres of a global pixel, scaled to the world's latitude: ground metres.
        let k = 2.0 * PI * 6_378_137.0 * self.plane_scale / world;
        let at = |i: f64, j: f64| {
            (
                (ox + i + 0.5 - world / 2.0) * k,
                (world / 2.0 - (oy + j + 0.5)) * k,
            )
        };
        let step = ((ground::WOOD_SPACING_M / self.m_per_px).floor() as usize).clamp(1, 16);
        let n = w.div_ceil(step) + 1;
        let lattice: Vec<f64> = (0..n * n)
            .map(|c| {
                let (u, v) = at(((c % n) * step) as f64, ((c / n) * step) as f64);
                ground::wood(u, v)
            })
            .collect();
        let data = pixmap.data_mut();
        for (j, row) in data.chunks_exact_mut(4 * w).enumerate() {
            let (gj, fj) = (j / step, (j % step) as f64 / step as f64);
            let fields = ground::Row::new(at(0.0, j as f64).1, self.m_per_px);
            for (i, px) in row.chunks_exact_mut(4).enumerate() {
                let (gi, fi) = (i / step, (i % step) as f64 / step as f64);
                let l = |a: usize, b: usize| lattice[(gj + b) * n + gi + a];
                let top = l(0, 0) + (l(1, 0) - l(0, 0)) * fi;
                let bottom = l(0, 1) + (l(1, 1) - l(0, 1)) * fi;
                let [r, g, b] = fields.colour(at(i as f64, j as f64).0, top + (bottom - top) * fj);
                px.copy_from_slice(&[r, g, b, 255]);
            }
        }
    }
}

fn paint(rgba: [u8; 4]) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(rgba[0], rgba[1], rgba[2], rgba[3]);
    p.anti_alias = true;
    p
}

/// A polyline in tile pixels (the subtraction in f64: global pixels outgrow f32's precision).
fn polyline(points: &[(f64, f64)], ox: f64, oy: f64) -> Option<Path> {
    let mut pb = PathBuilder::new();
    for (i, &(x, y)) in points.iter().enumerate() {
        let (x, y) = ((x - ox) as f32, (y - oy) as f32);
        if i == 0 {
            pb.move_to(x, y);
        } else {
            pb.line_to(x, y);
        }
    }
    pb.finish()
}

fn draw_road(pixmap: &mut Pixmap, road: &RoadPx, ox: f64, oy: f64) {
    let Some(path) = polyline(&road.points, ox, oy) else {
        return;
    };
    let stroke = |width: f64| Stroke {
        width: width as f32,
        line_cap: LineCap::Round,
        line_join: LineJoin::Round,
        ..Stroke::default()
    };
    let id = Transform::identity();
    pixmap.stroke_path(
        &path,
        &paint(ROAD_CASING),
        &stroke(road.width_px + 2.5),
        id,
        None,
    );
    pixmap.stroke_path(&path, &paint(ROAD), &stroke(road.width_px), id, None);
}

/// A disc hatched red, with its rim.
fn draw_area(pixmap: &mut Pixmap, cx: f64, cy: f64, r: f64) {
    let Some(disc) = PathBuilder::from_circle(cx as f32, cy as f32, r as f32) else {
        return;
    };
    let id = Transform::identity();
    let [red, green, blue] = AREA;
    pixmap.fill_path(
        &disc,
        &paint([red, green, blue, 46]),
        FillRule::Winding,
        id,
        None,
    );
    if let Some(mut mask) = Mask::new(pixmap.width(), pixmap.height()) {
        mask.fill_path(&disc, FillRule::Winding, true, id);
        let mut pb = PathBuilder::new();
        // Diagonals x − y = 8k: tiles start on multiples of 256, so the lines continue across
        // tiles. Only those through the disc and the tile.
        let step = 8.0;
        let lo = (cx - cy - 2.0 * r).max(-260.0);
        let hi = (cx - cy + 2.0 * r).min(260.0);
        let mut d = (lo / step).floor() * step;
        while d <= hi {
            pb.move_to(d as f32 - 300.0, -300.0);
            pb.line_to(d as f32 + 556.0, 556.0);
            d += step;
        }
        if let Some(hatch) = pb.finish() {
            let stroke = Stroke {
                width: 1.2,
                ..Stroke::default()
            };
            pixmap.stroke_path(
                &hatch,
                &paint([red, green, blue, 150]),
                &stroke,
                id,
                Some(&mask),
            );
        }
    }
    let rim = Stroke {
        width: 2.0,
        ..Stroke::default()
    };
    pixmap.stroke_path(&disc, &paint([red, green, blue, 230]), &rim, id, None);
}

/// An opaque pixmap as an RGB PNG.
fn encode(pixmap: &Pixmap) -> Result<Vec<u8>, String> {
    let rgb: Vec<u8> = pixmap
        .data()
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    let mut out = Vec::with_capacity(16 * 1024);
    let mut encoder = png::Encoder::new(&mut out, pixmap.width(), pixmap.height());
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(&rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())?;
    Ok(out)
}
