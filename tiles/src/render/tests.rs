use super::*;
use crate::mbtiles::MbTiles;
use crate::mercator::{self, Bounds, TileId};

const ORIGIN: LonLat = LonLat {
    lon: 8.545_594,
    lat: 47.397_742,
};

/// A point `east_m`, `north_m` from the origin (flat-Earth: fine over a few hundred metres).
fn at(east_m: f64, north_m: f64) -> LonLat {
    LonLat {
        lon: ORIGIN.lon + east_m / (M_PER_DEG * ORIGIN.lat.to_radians().cos()),
        lat: ORIGIN.lat + north_m / M_PER_DEG,
    }
}

fn world() -> TileWorld {
    TileWorld {
        name: "TEST".into(),
        center: ORIGIN,
        roads: vec![GeoRoad {
            name: "road1".into(),
            width_m: 10.0,
            points: vec![at(-400.0, 0.0), at(400.0, 0.0)],
        }],
        areas: vec![GeoArea {
            name: "NO-FLY".into(),
            center: at(150.0, 200.0),
            radius_m: 40.0,
        }],
    }
}

/// The RGB pixels of a PNG.
fn decode(png_bytes: &[u8]) -> (u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(png_bytes));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("a frame");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let px = buf[..info.buffer_size()]
        .chunks_exact(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width, px)
}

/// The tile holding `p` at zoom `z`, and `p`'s pixel in it.
fn tile_of(p: LonLat, z: u8) -> (TileId, usize, usize) {
    let (x, y) = mercator::to_pixel(p.lon, p.lat, z);
    let id = TileId::new(z, (x / 256.0) as u32, (y / 256.0) as u32).expect("tile");
    (
        id,
        (x - f64::from(id.x) * 256.0) as usize,
        (y - f64::from(id.y) * 256.0) as usize,
    )
}

#[test]
fn a_tile_over_a_road_has_the_road_colour_where_the_road_is_and_ground_beside_it() {
    let w = world();
    let z = 17;
    let scene = raster::Scene::new(&w, z);
    // 100 m east of the origin, on the road's centre line; 40 m north of it, ground.
    let (id, i, j) = tile_of(at(100.0, 0.0), z);
    let (width, px) = decode(&scene.tile(id).expect("render"));
    assert_eq!(width, 256);
    let pixel = |i: usize, j: usize| px[j * 256 + i];
    let road = [182, 178, 160];
    assert_eq!(pixel(i, j), road, "the road's centre at ({i}, {j})");
    // The road is 10 m wide: 12.7 px at zoom 17 here; ±4 px of the centre line is road.
    for dj in [-4_i32, 4] {
        let jj = (j as i32 + dj) as usize;
        if jj < 256 {
            assert_eq!(pixel(i, jj), road, "{dj} px off the centre line");
        }
    }
    let (id2, i2, j2) = tile_of(at(100.0, 40.0), z);
    let (_, px2) = decode(&scene.tile(id2).expect("render"));
    let ground = px2[j2 * 256 + i2];
    assert_ne!(ground, road);
    assert!(
        ground.iter().all(|&c| c < 110),
        "ground is dark: {ground:?}"
    );
    // The no-fly disc: reddish at its centre (its name may sit there: look beside it).
    let (id3, i3, j3) = tile_of(at(150.0, 200.0 - 25.0), z);
    let (_, px3) = decode(&scene.tile(id3).expect("render"));
    let c = px3[j3 * 256 + i3];
    assert!(
        c[0] > c[1] + 15 && c[0] > c[2] + 15,
        "red inside the disc: {c:?}"
    );
}

#[test]
fn a_world_renders_into_an_mbtiles_file_that_reads_back() {
    let dir = tempfile::tempdir().expect("dir");
    let out = dir.path().join("w.mbtiles");
    let options = RenderOptions {
        min_zoom: 13,
        max_zoom: 15,
        margin_m: 500.0,
        threads: 2,
    };
    let mut calls = Vec::new();
    let stats = render(&world(), &options, &out, false, |p| calls.push(p)).expect("render");
    let b = Bounds::parse(&world().bounds(500.0).to_metadata()).expect("bounds");
    let want: u64 = (13..=15).map(|z| b.tile_range(z).len()).sum();
    assert_eq!(stats.tiles, want);
    assert_eq!(
        calls.last(),
        Some(&Progress {
            done: want,
            total: want
        })
    );
    let m = MbTiles::open(&out).expect("open");
    let meta = m.metadata();
    assert_eq!((meta.min_zoom, meta.max_zoom), (13, 15));
    assert_eq!(meta.format, crate::format::TileFormat::Png);
    assert_eq!(meta.bounds, Some(b));
    assert_eq!(stats.bounds, b);
    assert_eq!(meta.attribution.as_deref(), Some(ATTRIBUTION));
    let counts = m.counts().expect("counts");
    assert_eq!(counts.iter().map(|c| c.tiles).sum::<u64>(), want);
    assert_eq!(counts.iter().map(|c| c.bytes).sum::<u64>(), stats.bytes);
    // Every tile of the range is there, none outside.
    for z in 13..=15 {
        let r = b.tile_range(z);
        for id in r.iter() {
            assert!(m.tile(id).expect("read").is_some(), "{id:?}");
        }
        let outside = TileId::new(z, r.x.end() + 1, *r.y.start()).expect("tile");
        assert!(m.tile(outside).expect("read").is_none());
    }
    // An existing file is kept unless overwritten.
    let e = render(&world(), &options, &out, false, |_| {}).expect_err("exists");
    assert!(e.to_string().contains("already exists"), "{e}");
    render(&world(), &options, &out, true, |_| {}).expect("overwritten");
}

#[test]
fn the_fingerprint_follows_the_world_and_the_options() {
    let o = RenderOptions::default();
    let a = world().fingerprint(&o);
    assert_eq!(a, world().fingerprint(&o));
    let mut moved = world();
    moved.areas[0].radius_m = 41.0;
    assert_ne!(a, moved.fingerprint(&o));
    let deeper = RenderOptions {
        max_zoom: 18,
        ..o.clone()
    };
    assert_ne!(a, world().fingerprint(&deeper));
    assert!(
        RenderOptions {
            min_zoom: 16,
            max_zoom: 15,
            ..o
        }
        .check()
        .is_err()
    );
}
