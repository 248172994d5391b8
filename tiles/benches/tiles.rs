//! The offline map's costs: one raster tile rendered (a road, the ground, a name), a small world
//! rendered into an MBTiles file on one thread, and one tile read from an MBTiles file as the
//! server reads it (the pooled read-only connection; HTTP not included). BENCHMARKS.md ("Map
//! tiles") records the figures.
//!
//! ```sh
//! cargo bench -p harrier-tiles --features render --bench tiles
//! ```

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use harrier_tiles::render::{self, GeoArea, GeoRoad, LonLat, RenderOptions, TileWorld};
use harrier_tiles::{MbTiles, TileId, mercator};

const ORIGIN: LonLat = LonLat {
    lon: 8.545_594,
    lat: 47.397_742,
};

/// A point `east_m`, `north_m` from the origin (flat-Earth; fine for a benchmark's world).
fn at(east_m: f64, north_m: f64) -> LonLat {
    LonLat {
        lon: ORIGIN.lon + east_m / (111_320.0 * ORIGIN.lat.to_radians().cos()),
        lat: ORIGIN.lat + north_m / 111_320.0,
    }
}

/// A winding 5 km road (a point every 10 m) and a no-fly disc: about the demo's world.
fn world() -> TileWorld {
    let points = (0..=500)
        .map(|i| {
            let s = f64::from(i) * 10.0;
            at(0.6 * s, 0.8 * s + 300.0 * (s / 800.0).sin())
        })
        .collect();
    TileWorld {
        name: "BENCH".into(),
        center: ORIGIN,
        roads: vec![GeoRoad {
            name: "road1".into(),
            width_m: 7.0,
            points,
        }],
        areas: vec![GeoArea {
            name: "NO-FLY".into(),
            center: at(200.0, 200.0),
            radius_m: 40.0,
        }],
    }
}

/// The tile at zoom `z` holding the point 300 m along the road.
fn tile_on_road(z: u8) -> TileId {
    let p = at(180.0, 240.0 + 300.0 * (300.0f64 / 800.0).sin());
    let (x, y) = mercator::to_pixel(p.lon, p.lat, z);
    TileId::new(z, (x / 256.0) as u32, (y / 256.0) as u32).expect("on the map")
}

fn bench(c: &mut Criterion) {
    let w = world();
    let mut g = c.benchmark_group("tiles");
    g.measurement_time(Duration::from_secs(5));
    for z in [13, 17] {
        let id = tile_on_road(z);
        g.bench_function(format!("render one tile z{z}"), |b| {
            b.iter(|| black_box(render::tile(&w, black_box(id)).expect("render")));
        });
    }
    let dir = tempfile::tempdir().expect("dir");
    let small = RenderOptions {
        min_zoom: 12,
        max_zoom: 15,
        margin_m: 1_000.0,
        threads: 1,
    };
    let out = dir.path().join("bench.mbtiles");
    g.sample_size(10);
    g.bench_function("render a file z12-15, one thread", |b| {
        b.iter(|| render::render(&w, &small, &out, true, |_| {}).expect("render"));
    });
    let tiles = MbTiles::open(&out).expect("open");
    let id = tile_on_road(15);
    g.sample_size(100);
    g.bench_function("read one tile", |b| {
        b.iter(|| black_box(tiles.tile(black_box(id)).expect("read").expect("a tile")));
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
