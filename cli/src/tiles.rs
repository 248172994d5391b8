//! `harrier tiles`: build (`render`) and inspect (`info`) the MBTiles files the dashboard's map
//! shows: the deployment's roads and no-fly areas (what `GET /api/v1/world` serves, in the frame
//! of `[frame] origin`) rendered by harrier-tiles into raster tiles around them
//! ([`crate::offline_map`]).

use std::io::{IsTerminal as _, Write as _};
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use harrier_server::config::{Config, ObstacleConfig};
use harrier_tiles::MbTiles;
use harrier_tiles::render::{self, Progress, RenderOptions};

use crate::demo::{self, DemoConfig};
use crate::offline_map::{DEMO_NAME, tile_world};

/// Arguments of `harrier tiles`.
#[derive(Debug, clap::Args)]
pub struct TilesArgs {
    #[command(subcommand)]
    command: TilesCommand,
}

#[derive(Debug, clap::Subcommand)]
enum TilesCommand {
    /// Render a deployment's roads and no-fly areas (a `harrier serve` configuration's, or the
    /// demo's) into raster tiles over a zoom range around them, as an MBTiles file for
    /// `[map] mbtiles`.
    Render(RenderArgs),
    /// Print an MBTiles file's metadata and its tiles per zoom level.
    Info {
        /// The MBTiles file.
        file: PathBuf,
    },
}

#[derive(Debug, clap::Args)]
struct RenderArgs {
    /// The MBTiles file to write (refused if it exists, unless --force).
    out: PathBuf,
    /// The world of this `harrier serve` configuration: `[frame] origin`, `[tracker] roads`,
    /// `[guidance] obstacles`.
    #[arg(
        long,
        value_name = "TOML",
        required_unless_present = "demo",
        conflicts_with = "demo"
    )]
    config: Option<PathBuf>,
    /// The world of `harrier demo` (with its `--obstacle`s).
    #[arg(long)]
    demo: bool,
    /// A no-fly circle `EAST,NORTH,RADIUS` (m) of the demo's world, as `harrier demo
    /// --obstacle` (repeatable).
    #[arg(long = "obstacle", value_name = "X,Y,R", value_parser = demo::parse_obstacle, requires = "demo")]
    obstacles: Vec<ObstacleConfig>,
    /// The map's name, written at the origin (ASCII).
    #[arg(long)]
    name: Option<String>,
    /// Lowest zoom level.
    #[arg(long, default_value_t = RenderOptions::default().min_zoom)]
    min_zoom: u8,
    /// Highest zoom level (the page scales its tiles beyond).
    #[arg(long, default_value_t = RenderOptions::default().max_zoom)]
    max_zoom: u8,
    /// Ground around the roads and areas (m).
    #[arg(long, default_value_t = RenderOptions::default().margin_m)]
    margin: f64,
    /// Rendering threads (default: every core).
    #[arg(long)]
    threads: Option<usize>,
    /// Overwrite an existing file.
    #[arg(long)]
    force: bool,
}

/// Runs `harrier tiles`.
pub fn run(args: &TilesArgs) -> anyhow::Result<()> {
    match &args.command {
        TilesCommand::Render(r) => run_render(r),
        TilesCommand::Info { file } => info(file),
    }
}

fn run_render(args: &RenderArgs) -> anyhow::Result<()> {
    let (config, name) = if args.demo {
        let demo = DemoConfig {
            obstacles: args.obstacles.clone(),
            ..DemoConfig::default()
        };
        let scenario = demo::scenario().context("the demo's world")?;
        (demo::server_config(&demo, &scenario), DEMO_NAME.to_owned())
    } else {
        let path = args.config.as_deref().context("--config or --demo")?;
        let name = path
            .file_stem()
            .map_or_else(|| "HARRIER".into(), |s| s.to_string_lossy().to_uppercase());
        (Config::load(path)?, name)
    };
    let world = tile_world(&config, args.name.as_deref().unwrap_or(&name));
    let options = RenderOptions {
        min_zoom: args.min_zoom,
        max_zoom: args.max_zoom,
        margin_m: args.margin,
        threads: args
            .threads
            .unwrap_or(RenderOptions::default().threads)
            .max(1),
    };
    options.check().map_err(anyhow::Error::msg)?;
    let tty = std::io::stderr().is_terminal();
    let mut last = 0;
    let stats = render::render(&world, &options, &args.out, args.force, |p: Progress| {
        // A line per tenth (a rewritten line on a terminal).
        let tenth = 10 * p.done / p.total.max(1);
        if tty {
            eprint!(
                "\rrendering: {}/{} tiles ({} %)",
                p.done,
                p.total,
                100 * p.done / p.total.max(1)
            );
        } else if tenth > last || p.done == p.total {
            eprintln!("rendering: {}/{} tiles", p.done, p.total);
        }
        last = tenth;
    })?;
    if tty {
        eprintln!();
    }
    let b = stats.bounds;
    let _ = writeln!(
        std::io::stdout().lock(),
        "wrote {}: {} tiles (zoom {}–{}), {:.1} MB, in {:.1} s; bounds {:.5},{:.5},{:.5},{:.5}",
        args.out.display(),
        stats.tiles,
        options.min_zoom,
        options.max_zoom,
        stats.bytes as f64 / 1e6,
        stats.elapsed.as_secs_f64(),
        b.west,
        b.south,
        b.east,
        b.north,
    );
    Ok(())
}

fn info(file: &Path) -> anyhow::Result<()> {
    let m = MbTiles::open(file)?;
    let meta = m.metadata();
    let mut out = String::new();
    use std::fmt::Write as _;
    let _ = writeln!(out, "{}", file.display());
    let _ = writeln!(out, "  format      {}", meta.format.name());
    let _ = writeln!(out, "  zoom        {}–{}", meta.min_zoom, meta.max_zoom);
    if let Some(b) = meta.bounds {
        let _ = writeln!(out, "  bounds      {}", b.to_metadata());
    }
    for (k, v) in &meta.entries {
        if !["format", "minzoom", "maxzoom", "bounds", "json"].contains(&k.as_str()) {
            let _ = writeln!(out, "  {k:<11} {v}");
        }
    }
    let counts = m.counts()?;
    for c in &counts {
        let _ = writeln!(
            out,
            "  zoom {:>2}  {:>8} tiles  {:>9.1} kB",
            c.zoom,
            c.tiles,
            c.bytes as f64 / 1e3
        );
    }
    let (n, bytes) = counts
        .iter()
        .fold((0, 0), |(n, b), c| (n + c.tiles, b + c.bytes));
    let _ = writeln!(
        out,
        "  total    {n:>8} tiles  {:>9.1} kB",
        bytes as f64 / 1e3
    );
    let _ = std::io::stdout().lock().write_all(out.as_bytes());
    Ok(())
}

#[cfg(test)]
mod tests {
    use harrier_link::geo::LocalFrame;
    use harrier_server::world::WorldBody;

    use super::*;

    /// The demo's road in WGS-84 is where the frame puts its ENU points.
    #[test]
    fn the_tile_world_is_the_configurations_world_in_wgs84() {
        let scenario = demo::scenario().expect("scenario");
        let demo = DemoConfig {
            obstacles: vec![ObstacleConfig {
                x_m: 100.0,
                y_m: -200.0,
                radius_m: 40.0,
            }],
            ..DemoConfig::default()
        };
        let config = demo::server_config(&demo, &scenario);
        let w = tile_world(&config, "X");
        let frame = LocalFrame::new(config.frame.origin);
        let road = &WorldBody::of(&config).roads[0];
        assert_eq!(w.roads[0].points.len(), road.points.len());
        for (g, p) in w.roads[0].points.iter().zip(&road.points) {
            let back = frame.to_enu(&harrier_link::geo::Geodetic::new(
                g.lat,
                g.lon,
                config.frame.origin.alt_m + config.frame.plane_z,
            ));
            assert!(
                (back.x - p[0]).abs() < 0.01 && (back.y - p[1]).abs() < 0.01,
                "{back:?} {p:?}"
            );
        }
        assert_eq!(w.areas.len(), 1);
        assert_eq!(w.areas[0].radius_m, 40.0);
        assert!((w.center.lat - config.frame.origin.lat_deg).abs() < 1e-9);
    }
}
