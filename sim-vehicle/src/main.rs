//! `harrier-sim`: simulated UAVs that MAVLink clients can fly like PX4 SITL instances.
//!
//! ```not_rust
//! harrier-sim                        # vehicle 1: GCS udpout:127.0.0.1:14550, API udpin:0.0.0.0:14540
//! harrier-sim --count 3              # vehicles 1-3, API ports 14540-14542
//! harrier-sim --airframe fixed-wing --gcs none --api udpin:127.0.0.1:14600
//! harrier-sim --autopilot ardupilot --api tcpin:127.0.0.1:5760      # an ArduCopter for MAVProxy
//! harrier-sim --autopilot ardupilot --airframe fixed-wing          # an ArduPlane
//! harrier-sim --zenoh-mode client --zenoh-connect tls/router.example:7447 \
//!     --zenoh-tls-root-ca ca.pem --zenoh-tls-cert uav1.pem --zenoh-tls-key uav1.key  # docs/deploy.md
//! harrier-sim --signing-key-file key.hex        # MAVLink 2 signing, signed frames only
//! harrier-sim record --scenario cimm-road --seed 1 --duration 300 --out /tmp/run   # offline
//! ```

use std::process::ExitCode;

use clap::{Parser, ValueEnum};
use harrier_link::autopilot::Autopilot;
use harrier_link::bus::{BusConfig, Mode, TlsConfig};
use harrier_link::geo::Geodetic;
use harrier_link::signing::{Signing, SigningKey, SigningMode};
use harrier_sim::bus::Bus;
use harrier_sim::net::{Endpoint, LinkConfig, SimHandle, spawn};
use harrier_sim::sensor_loop::{SensorLoopConfig, SensorLoopHandle};
use harrier_sim::setup::SimScenario;
use harrier_sim::vehicle::{
    Airframe, ClockSkew, DEFAULT_BATTERY_DRAIN_PCT_MIN, Vehicle, VehicleConfig,
};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum AirframeArg {
    /// Hovers (MAV_TYPE_QUADROTOR; ArduCopter under --autopilot ardupilot).
    Multirotor,
    /// Minimum airspeed, bank-limited turns, loiters (MAV_TYPE_FIXED_WING; ArduPlane).
    FixedWing,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum AutopilotArg {
    /// PX4: MAV_AUTOPILOT_PX4, PX4's modes (main/sub custom mode), OFFBOARD.
    Px4,
    /// ArduPilot: MAV_AUTOPILOT_ARDUPILOTMEGA, ArduCopter's or ArduPlane's mode numbers,
    /// GUIDED, its parameters and commands (docs/autopilots.md).
    Ardupilot,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SigningArg {
    /// No signing.
    Off,
    /// Sign every frame sent; accept unsigned frames (refuse wrongly signed and replayed ones).
    Sign,
    /// Sign every frame sent; accept only correctly signed, fresh frames.
    #[value(name = "signed_only", alias = "signed-only")]
    SignedOnly,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ZenohModeArg {
    Peer,
    Client,
}

impl From<ZenohModeArg> for Mode {
    fn from(m: ZenohModeArg) -> Self {
        match m {
            ZenohModeArg::Peer => Self::Peer,
            ZenohModeArg::Client => Self::Client,
        }
    }
}

/// Simulated UAVs speaking MAVLink 2 as PX4 or ArduPilot (sysid = vehicle id, compid 1).
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
    /// The autopilot the vehicles behave as (HEARTBEAT, modes, commands, parameters).
    #[arg(long, value_enum, default_value_t = AutopilotArg::Px4)]
    autopilot: AutopilotArg,
    /// GCS link, shared by all vehicles' telemetry (`none` to disable).
    #[arg(long, default_value = "udpout:127.0.0.1:14550")]
    gcs: String,
    /// API link of the first vehicle (udpin:, udpout:, tcpin: or tcpout:HOST:PORT); the port grows
    /// by one per further vehicle. Default: udpin:0.0.0.0:{14540 + id - 1}.
    #[arg(long)]
    api: Option<String>,
    /// MAVLink 2 signing key: a file of 64 hex characters or exactly 32 raw bytes (pymavlink's
    /// key; from a passphrase: `printf %s PASSPHRASE | sha256sum | cut -c1-64 > key.hex`).
    #[arg(long, value_name = "PATH")]
    signing_key_file: Option<std::path::PathBuf>,
    /// MAVLink 2 signing on every link. Default: signed_only with --signing-key-file, else off.
    #[arg(long, value_enum)]
    signing: Option<SigningArg>,
    /// Link id written in this simulator's signatures.
    #[arg(long, default_value_t = 0)]
    signing_link_id: u8,
    /// Home / geodetic origin: LAT,LON,ALT_AMSL (degrees, metres). Default: the scenario's
    /// origin (PX4 SITL's Zurich home for the presets).
    #[arg(long, value_parser = parse_home)]
    home: Option<Geodetic>,
    /// World and sensors: a preset (cimm-road, leader, radar, radar-abrupt, radar-markov,
    /// crossing) or a JSON file.
    #[arg(long, default_value = "crossing")]
    scenario: String,
    /// Seed of the world and the sensors.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Scan rate of every sensor (Hz), overriding the scenario's.
    #[arg(long)]
    detection_hz: Option<f64>,
    /// Make the clock that stamps `time_unix` on detections and truth wrong by this many
    /// seconds (positive: ahead), to test how a ground station copes with a wrong clock.
    #[arg(
        long,
        default_value_t = 0.0,
        allow_negative_numbers = true,
        value_name = "S"
    )]
    clock_offset_s: f64,
    /// Make that clock drift by this many µs per second (parts per million).
    #[arg(
        long,
        default_value_t = 0.0,
        allow_negative_numbers = true,
        value_name = "PPM"
    )]
    clock_drift_ppm: f64,
    /// Battery drain while armed (percent of a full charge per simulated minute; the default
    /// empties it in 30 minutes).
    #[arg(long, default_value_t = DEFAULT_BATTERY_DRAIN_PCT_MIN, value_name = "PCT")]
    battery_drain_pct_min: f64,
    /// Rate of the simulation-only truth on harrier/v1/sim/truth (Hz).
    #[arg(long, default_value_t = 10.0)]
    truth_hz: f64,
    /// Do not publish detections (MAVLink only).
    #[arg(long)]
    no_zenoh: bool,
    /// Zenoh session mode.
    #[arg(long, value_enum, default_value_t = ZenohModeArg::Peer)]
    zenoh_mode: ZenohModeArg,
    /// Zenoh endpoint to connect to (repeatable); retried in the background while absent.
    #[arg(long, default_values_t = ["tcp/127.0.0.1:7447".to_owned()])]
    zenoh_connect: Vec<String>,
    /// Zenoh endpoint to listen on (repeatable), e.g. tcp/127.0.0.1:7448.
    #[arg(long)]
    zenoh_listen: Vec<String>,
    /// Enable Zenoh multicast scouting (off by default: nothing leaks onto the LAN).
    #[arg(long)]
    zenoh_scouting: bool,
    /// For tls/HOST:PORT endpoints: the certificate authority (PEM file) that signed the
    /// router's certificate.
    #[arg(long, value_name = "PEM")]
    zenoh_tls_root_ca: Option<String>,
    /// Mutual TLS: this companion's certificate (PEM), presented to the router, whose access
    /// control names it by common name (needs --zenoh-tls-key).
    #[arg(long, value_name = "PEM", requires = "zenoh_tls_key")]
    zenoh_tls_cert: Option<String>,
    /// The private key (PEM) of --zenoh-tls-cert.
    #[arg(long, value_name = "PEM", requires = "zenoh_tls_cert")]
    zenoh_tls_key: Option<String>,
    #[command(subcommand)]
    command: Option<SubCommand>,
}

#[derive(Debug, clap::Subcommand)]
enum SubCommand {
    /// Run a scenario offline (no sockets, no wall clock) and write a gcs-scenario/1 directory.
    Record(harrier_sim::record::RecordArgs),
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

/// The API endpoint of the `k`-th vehicle: the first one's, with its port plus `k` (any link kind).
fn api_endpoint(args: &Args, id: u8, k: u16) -> Result<String, String> {
    let first = args
        .api
        .clone()
        .unwrap_or_else(|| format!("udpin:0.0.0.0:{}", 14540 + u16::from(args.id) - 1));
    let endpoint = Endpoint::parse(&first).map_err(|e| e.to_string())?;
    let mut addr = endpoint.addr();
    let port = addr
        .port()
        .checked_add(k)
        .filter(|_| addr.port() != 0 || k == 0)
        .ok_or_else(|| format!("no API port for vehicle {id}"))?;
    addr.set_port(port);
    Ok(endpoint.with_addr(addr).to_string())
}

/// The signing settings of the command line (`None`: off).
fn signing(args: &Args) -> Result<Option<Signing>, String> {
    let mode = match (args.signing, &args.signing_key_file) {
        (Some(SigningArg::Off), _) | (None, None) => return Ok(None),
        (Some(SigningArg::Sign), _) => SigningMode::Sign,
        (Some(SigningArg::SignedOnly) | None, _) => SigningMode::SignedOnly,
    };
    let path = args
        .signing_key_file
        .as_ref()
        .ok_or_else(|| format!("--signing {mode} needs --signing-key-file"))?;
    let key = SigningKey::from_file(path).map_err(|e| e.to_string())?;
    Ok(Some(Signing {
        key,
        mode,
        link_id: args.signing_link_id,
    }))
}

/// The scenario with the command line's overrides (home, detection rate).
fn scenario(args: &Args) -> Result<SimScenario, String> {
    let mut scenario = SimScenario::load(&args.scenario).map_err(|e| e.to_string())?;
    if let Some(home) = args.home {
        scenario.origin = home;
    }
    if let Some(hz) = args.detection_hz {
        if !(hz.is_finite() && hz > 0.0 && hz <= 1000.0) {
            return Err(format!("--detection-hz {hz} must be in (0, 1000]"));
        }
        for s in &mut scenario.sensors {
            s.rate_hz = hz;
        }
    }
    Ok(scenario)
}

/// Starts the vehicles and, unless `--no-zenoh`, the sensor loop publishing over Zenoh.
fn run(args: &Args) -> Result<(Vec<SimHandle>, Option<SensorLoopHandle>), String> {
    if !(args.speedup.is_finite() && args.speedup > 0.0 && args.speedup <= 100.0) {
        return Err("--speedup must be in (0, 100]".to_owned());
    }
    if !(args.battery_drain_pct_min.is_finite() && args.battery_drain_pct_min >= 0.0) {
        return Err("--battery-drain-pct-min must be finite and at least 0".to_owned());
    }
    if !(args.truth_hz.is_finite() && args.truth_hz > 0.0 && args.truth_hz <= 1000.0) {
        return Err("--truth-hz must be in (0, 1000]".to_owned());
    }
    let scenario = scenario(args)?;
    let signing = signing(args)?;
    if let Some(s) = &signing {
        eprintln!(
            "harrier-sim: MAVLink signing {} (link id {})",
            s.mode, s.link_id
        );
    }
    let origin = scenario.origin;
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
            autopilot: match args.autopilot {
                AutopilotArg::Px4 => Autopilot::Px4,
                AutopilotArg::Ardupilot => Autopilot::ArduPilot,
            },
            origin,
            speedup: args.speedup,
            clock: skew(args),
            battery_drain_pct_min: args.battery_drain_pct_min,
        };
        let links = LinkConfig {
            endpoints,
            signing: signing.clone(),
        };
        let sim = spawn(config, &links).map_err(|e| e.to_string())?;
        eprintln!(
            "harrier-sim: vehicle {id} up, links {:?}",
            sim.local_addrs()
        );
        sims.push(sim);
    }
    if args.no_zenoh {
        return Ok((sims, None));
    }
    let bus = Bus::open(&BusConfig {
        mode: args.zenoh_mode.into(),
        connect: args.zenoh_connect.clone(),
        listen: args.zenoh_listen.clone(),
        multicast_scouting: args.zenoh_scouting,
        tls: TlsConfig {
            root_ca_certificate: args.zenoh_tls_root_ca.clone(),
            connect_certificate: args.zenoh_tls_cert.clone(),
            connect_private_key: args.zenoh_tls_key.clone(),
            enable_mtls: args.zenoh_tls_cert.is_some(),
            ..TlsConfig::default()
        },
    })
    .map_err(|e| e.to_string())?;
    let config = SensorLoopConfig {
        scenario,
        seed: args.seed,
        speedup: args.speedup,
        truth_hz: args.truth_hz,
        clock: skew(args),
    };
    let live =
        harrier_sim::sensor_loop::spawn(&config, sims.iter().map(SimHandle::shared).collect(), bus)
            .map_err(|e| e.to_string())?;
    eprintln!(
        "harrier-sim: publishing detections on harrier/v1/vehicle/{{id}}/detections (zenoh {}, connect {:?}, listen {:?})",
        Mode::from(args.zenoh_mode),
        args.zenoh_connect,
        args.zenoh_listen
    );
    Ok((sims, Some(live)))
}

fn main() -> ExitCode {
    let args = Args::parse();
    if let Some(SubCommand::Record(r)) = &args.command {
        return match harrier_sim::record::run(r) {
            Ok(stats) => {
                eprintln!(
                    "harrier-sim record: wrote {} ({}): {} scans, {} target detections, {} clutter, {} truth rows",
                    r.out.display(),
                    if stats.multi {
                        "gcs-scenario/1 + FORMAT-MULTI"
                    } else {
                        "gcs-scenario/1"
                    },
                    stats.scans,
                    stats.detections,
                    stats.clutter,
                    stats.truth_rows
                );
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("harrier-sim record: {e}");
                ExitCode::from(2)
            }
        };
    }
    match run(&args) {
        Ok((sims, _live)) => {
            // The vehicles live on their own threads; stdin takes the operator's lines until it
            // ends, then the simulator runs until interrupted.
            for line in std::io::stdin().lines() {
                let Ok(line) = line else { break };
                if line.trim().is_empty() {
                    continue;
                }
                match stdin_command(&line, |id| {
                    sims.iter()
                        .find(|s| s.vehicle().id() == id)
                        .map(SimHandle::vehicle)
                }) {
                    Ok(done) => eprintln!("harrier-sim: {done}"),
                    Err(e) => eprintln!("harrier-sim: {line:?}: {e}"),
                }
            }
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

/// One line of stdin, applied to the vehicle `vehicle` finds by id:
///
/// - `pilot ID MODE`: the pilot's mode switch (`Vehicle::pilot_switch`): vehicle ID changes to
///   MODE (a name of its autopilot's table: `HOLD`, `RTL`, `POSCTL`, `LOITER`, …) by itself, as
///   an RC flight-mode switch would;
/// - `battery ID PERCENT`: its battery's remaining charge (its failsafe acts on the next step).
///
/// What was done, or why not.
fn stdin_command<G: std::ops::DerefMut<Target = Vehicle>>(
    line: &str,
    vehicle: impl Fn(u8) -> Option<G>,
) -> Result<String, String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let [verb, id, arg] = words[..] else {
        return Err("expected `pilot ID MODE` or `battery ID PERCENT`".to_owned());
    };
    let id: u8 = id.parse().map_err(|_| format!("bad vehicle id {id:?}"))?;
    let mut v = vehicle(id).ok_or_else(|| format!("no vehicle {id}"))?;
    match verb {
        "pilot" => {
            let mode = v
                .personality()
                .mode_named(arg)
                .ok_or_else(|| format!("{arg:?} is not a {} mode", v.personality().label()))?;
            if v.pilot_switch(mode) {
                Ok(format!("vehicle {id}: pilot switched to {arg}"))
            } else {
                Err(format!(
                    "vehicle {id} refused {arg} (still {})",
                    v.mode().name()
                ))
            }
        }
        "battery" => {
            let pct: f64 = arg
                .parse()
                .ok()
                .filter(|p: &f64| (0.0..=100.0).contains(p))
                .ok_or_else(|| format!("bad percentage {arg:?}"))?;
            v.set_battery(pct / 100.0);
            Ok(format!("vehicle {id}: battery at {pct} %"))
        }
        _ => Err(format!("unknown command {verb:?}")),
    }
}

/// The wrong clock `--clock-offset-s` and `--clock-drift-ppm` ask for.
fn skew(args: &Args) -> ClockSkew {
    ClockSkew {
        offset_s: args.clock_offset_s,
        drift_ppm: args.clock_drift_ppm,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `pilot` switches the vehicle's mode by itself, `battery` sets its charge; bad lines are
    /// refused with a reason and change nothing.
    #[test]
    fn stdin_lines_switch_modes_and_set_the_battery() {
        use harrier_sim::vehicle::FlightMode;
        let v = std::sync::Mutex::new(Vehicle::new(VehicleConfig::new(3), 0.0));
        let find = |id: u8| (id == 3).then(|| v.lock().expect("lock"));
        assert!(stdin_command("pilot 3 POSCTL", find).is_ok());
        assert_eq!(
            v.lock().expect("lock").mode(),
            harrier_link::autopilot::Mode::Px4(FlightMode::Position)
        );
        assert!(stdin_command("pilot 3 OFFBOARD", find).is_err_and(|e| e.contains("refused")));
        assert!(stdin_command("pilot 3 GUIDED", find).is_err_and(|e| e.contains("px4-mc")));
        assert!(stdin_command("pilot 4 HOLD", find).is_err_and(|e| e.contains("no vehicle 4")));
        assert!(stdin_command("battery 3 20", find).is_ok());
        assert!((v.lock().expect("lock").battery_remaining() - 0.2).abs() < 1e-12);
        assert!(stdin_command("battery 3 120", find).is_err());
        assert!(stdin_command("fly 3 x", find).is_err());
        assert!(stdin_command("pilot 3", find).is_err());
        assert_eq!(
            v.lock().expect("lock").mode(),
            harrier_link::autopilot::Mode::Px4(FlightMode::Position)
        );
    }

    #[test]
    fn api_ports_grow_per_vehicle_for_every_link_kind() {
        let args = |api: &str| Args::try_parse_from(["harrier-sim", "--count", "3", "--api", api]);
        for (api, third) in [
            ("udpin:127.0.0.1:14600", "udpin:127.0.0.1:14602"),
            ("udpout:127.0.0.1:14600", "udpout:127.0.0.1:14602"),
            ("tcpin:127.0.0.1:5760", "tcpin:127.0.0.1:5762"),
            ("tcp:127.0.0.1:5760", "tcpout:127.0.0.1:5762"),
        ] {
            let a = args(api).expect("parse");
            assert_eq!(api_endpoint(&a, 3, 2).as_deref(), Ok(third));
        }
        let a = Args::try_parse_from(["harrier-sim", "--id", "2"]).expect("parse");
        assert_eq!(api_endpoint(&a, 2, 0).as_deref(), Ok("udpin:0.0.0.0:14541"));
        let a = args("tcpin:127.0.0.1:0").expect("parse");
        assert!(api_endpoint(&a, 2, 1).is_err());
        let a = args("tcpin:127.0.0.1:65535").expect("parse");
        assert!(api_endpoint(&a, 2, 1).is_err());
        let a = args("serial:/dev/ttyUSB0").expect("parse");
        assert!(api_endpoint(&a, 1, 0).is_err_and(|e| e.contains("tcpin:HOST:PORT")));
    }

    #[test]
    fn signing_flags() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let key = dir.path().join("key.hex");
        std::fs::write(&key, format!("{}\n", "ab".repeat(32))).expect("write key");
        let bad = dir.path().join("bad.hex");
        std::fs::write(&bad, "not a key").expect("write key");
        let parse = |extra: &[&str]| {
            let mut argv = vec!["harrier-sim"];
            argv.extend_from_slice(extra);
            signing(&Args::try_parse_from(argv).expect("parse"))
        };
        let key_arg = key.to_str().expect("utf-8 path");
        assert_eq!(parse(&[]), Ok(None));
        let s = parse(&["--signing-key-file", key_arg])
            .expect("signing")
            .expect("on");
        assert_eq!((s.mode, s.link_id), (SigningMode::SignedOnly, 0));
        assert_eq!(s.key.bytes(), &[0xAB; 32]);
        let s = parse(&[
            "--signing-key-file",
            key_arg,
            "--signing",
            "sign",
            "--signing-link-id",
            "7",
        ])
        .expect("signing")
        .expect("on");
        assert_eq!((s.mode, s.link_id), (SigningMode::Sign, 7));
        assert_eq!(
            parse(&["--signing-key-file", key_arg, "--signing", "off"]),
            Ok(None)
        );
        assert!(
            parse(&["--signing", "signed_only"]).is_err_and(|e| e.contains("--signing-key-file"))
        );
        let bad_arg = bad.to_str().expect("utf-8 path");
        assert!(parse(&["--signing-key-file", bad_arg]).is_err_and(|e| e.contains("64 hex")));
    }
}
