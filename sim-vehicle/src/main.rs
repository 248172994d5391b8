//! `harrier-sim`: simulated UAVs that MAVLink clients can fly like PX4 SITL instances.
//!
//! ```not_rust
//! harrier-sim                        # vehicle 1: GCS udpout:127.0.0.1:14550, API udpin:0.0.0.0:14540
//! harrier-sim --count 3              # vehicles 1-3, API ports 14540-14542
//! harrier-sim --airframe fixed-wing --gcs none --api udpin:127.0.0.1:14600
//! ```

use std::process::ExitCode;

use clap::{Parser, ValueEnum};
use harrier_sim::geo::Geodetic;
use harrier_sim::net::{Endpoint, LinkConfig, SimHandle, spawn};
use harrier_sim::vehicle::{Airframe, VehicleConfig};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum AirframeArg {
    Multirotor,
    FixedWing,
}

/// Simulated UAVs speaking MAVLink 2 with PX4 conventions (sysid = vehicle id, compid 1).
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// MAVLink system id of the first vehicle (1-255).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..))]
    id: u8,
    /// Number of vehicles (consecutive ids and API ports).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=255))]
    count: u16,
    /// Simulated seconds per wall-clock second.
    #[arg(long, default_value_t = 1.0)]
    speedup: f64,
    /// Airframe.
    #[arg(long, value_enum, default_value_t = AirframeArg::Multirotor)]
    airframe: AirframeArg,
    /// GCS link, shared by all vehicles' telemetry (`none` to disable).
    #[arg(long, default_value = "udpout:127.0.0.1:14550")]
    gcs: String,
    /// API link of the first vehicle; the port grows by one per further vehicle.
    /// Default: udpin:0.0.0.0:{14540 + id - 1}.
    #[arg(long)]
    api: Option<String>,
    /// Home / geodetic origin: LAT,LON,ALT_AMSL (degrees, metres).
    #[arg(long, default_value = "47.397742,8.545594,488.0", value_parser = parse_home)]
    home: Geodetic,
}

fn parse_home(s: &str) -> Result<Geodetic, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [lat, lon, alt]
            if (-90.0..=90.0).contains(&lat)
                && (-180.0..=180.0).contains(&lon)
                && alt.is_finite() =>
        {
            Ok(Geodetic::new(lat, lon, alt))
        }
        _ => Err("expected LAT,LON,ALT with |LAT| <= 90 and |LON| <= 180".to_owned()),
    }
}

/// The API endpoint of the `k`-th vehicle: the first one's port plus `k`.
fn api_endpoint(args: &Args, id: u8, k: u16) -> Result<String, String> {
    let first = args
        .api
        .clone()
        .unwrap_or_else(|| format!("udpin:0.0.0.0:{}", 14540 + u16::from(args.id) - 1));
    let (kind, addr) = match Endpoint::parse(&first).map_err(|e| e.to_string())? {
        Endpoint::UdpIn(a) => ("udpin", a),
        Endpoint::UdpOut(a) => ("udpout", a),
    };
    let port = addr
        .port()
        .checked_add(k)
        .filter(|_| addr.port() != 0 || k == 0)
        .ok_or_else(|| format!("no API port for vehicle {id}"))?;
    let mut a = addr;
    a.set_port(port);
    Ok(format!("{kind}:{a}"))
}

fn run(args: &Args) -> Result<Vec<SimHandle>, String> {
    if !(args.speedup.is_finite() && args.speedup > 0.0 && args.speedup <= 100.0) {
        return Err("--speedup must be in (0, 100]".to_owned());
    }
    let mut sims = Vec::new();
    for k in 0..args.count {
        let id = u8::try_from(u16::from(args.id) + k)
            .map_err(|_| "--id + --count - 1 must be at most 255".to_owned())?;
        let mut endpoints = Vec::new();
        if args.gcs != "none" {
            endpoints.push(args.gcs.clone());
        }
        endpoints.push(api_endpoint(args, id, k)?);
        let config = VehicleConfig {
            id,
            airframe: match args.airframe {
                AirframeArg::Multirotor => Airframe::Multirotor,
                AirframeArg::FixedWing => Airframe::FixedWing,
            },
            origin: args.home,
            speedup: args.speedup,
        };
        let sim = spawn(config, &LinkConfig { endpoints }).map_err(|e| e.to_string())?;
        eprintln!(
            "harrier-sim: vehicle {id} up, links {:?}",
            sim.local_addrs()
        );
        sims.push(sim);
    }
    Ok(sims)
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(_sims) => {
            // Run until interrupted: the vehicles live on their own threads.
            loop {
                std::thread::park();
            }
        }
        Err(e) => {
            eprintln!("harrier-sim: {e}");
            ExitCode::from(2)
        }
    }
}
