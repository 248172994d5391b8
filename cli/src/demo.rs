//! `harrier demo`: the live service, an in-process Zenoh peer and simulated UAVs in one process.
//!
//! [`start`] opens the live service ([`harrier_server::start`]) with its Zenoh session listening on a
//! free loopback port, then starts harrier-sim's world ([`SimWorld`]) whose session connects to
//! it: the `cimm-road` preset with its car slowed to 5 m/s, a second car ahead on the road and a
//! camera slaved to each car on every UAV. The UAVs stand on the ground at home and send their
//! MAVLink to the service's GCS link (`--gcs`, PX4's UDP 14550). The service tracks with the
//! preset's road and motion models (CIMM by default); once every car has a confirmed track whose
//! speed is known within 0.5 m/s (or 30 s after the first), the demo assigns every UAV to the
//! slowest one with TOGVF and phase spacing (`--radius`, `--height`), and the guidance loop arms
//! them, takes them off and flies the standoff; when the tracker deletes that track, the demo
//! assigns them again. [`run`] is the command: it starts the demo, prints where to point a
//! browser and waits for Ctrl-C.

use std::net::SocketAddr;
use std::path::PathBuf;

use harrier_link::autopilot::{Frame, Personality};
use harrier_sim::embedded::{SimWorld, WorldConfig, WorldError, WorldVehicle};
use harrier_sim::sensor_loop::SensorLoopConfig;
use harrier_sim::setup::{ScenarioError, SensorType, SimScenario, TargetMotion};

use harrier_server::config::{
    Config, CotConfig, CotDestination, CotEncoding, CotTransport, ObstacleConfig, SigningConfig,
};
use harrier_server::{LiveError, LiveServer};

mod assigner;

use self::assigner::Assigner;

/// Arguments of `harrier demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
    /// Address of the web page and the HTTP API (port 0: any free port).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,
    /// Simulated seconds per wall-clock second, in (0, 100].
    #[arg(long, default_value_t = 1.0)]
    pub speedup: f64,
    /// Seed of the simulated world and of every sensor's noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of simulated UAVs (MAVLink system ids 1…N), PX4 multirotors.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..), conflicts_with = "fleet")]
    pub vehicles: u8,
    /// The simulated UAVs by autopilot and airframe, one per entry (system ids 1…N, in order):
    /// px4-mc, ardupilot-mc (ArduCopter), px4-fw, ardupilot-fw (ArduPlane), e.g.
    /// `--fleet px4-mc,ardupilot-mc,px4-fw,ardupilot-fw`. With a fixed wing in the fleet the
    /// assigned car crawls at 1.5 m/s and the standoff's relative speed is 12.5 m/s, the band in
    /// which a 15 m/s multirotor and a 10 m/s-minimum fixed wing share one ring.
    #[arg(long, value_delimiter = ',', value_parser = parse_personality, conflicts_with = "vehicles")]
    pub fleet: Vec<Personality>,
    /// Record the session into this SQLite file (created if missing; `harrier sessions` reads
    /// it).
    #[arg(long, value_name = "SQLITE")]
    pub record: Option<PathBuf>,
    /// Track filter: ekf, cdkf, imm or cimm (road-constrained IMM on the demo's road).
    #[arg(long, short, default_value = "cimm")]
    pub estimator: String,
    /// The GCS link the simulated UAVs send their MAVLink to (PX4's UDP 14550).
    #[arg(long, default_value = "udpin:127.0.0.1:14550")]
    pub gcs: String,
    /// MAVLink router endpoints for QGroundControl, MAVProxy or MAVSDK (repeatable; `none`
    /// for none).
    #[arg(long = "router", default_values = ["udpin:127.0.0.1:14551", "tcpin:127.0.0.1:5760"])]
    pub router: Vec<String>,
    /// Do not assign the UAVs to a track (fly nothing; assign through the API or the page).
    #[arg(long)]
    pub no_assign: bool,
    /// Standoff radius R (m) of the demo's assignment.
    #[arg(long, default_value_t = 150.0)]
    pub radius: f64,
    /// Height H (m) above the target of the demo's assignment.
    #[arg(long, default_value_t = 300.0)]
    pub height: f64,
    /// A no-fly circle `EAST,NORTH,RADIUS` (m, in the demo's frame) that the `formation` law
    /// steers around and the map draws (repeatable).
    #[arg(long = "obstacle", value_name = "X,Y,R", value_parser = parse_obstacle)]
    pub obstacles: Vec<ObstacleConfig>,
    /// MAVLink 2 signing, `signed_only`, of the GCS link, the router and the simulated UAVs, with
    /// this key file (64 hex characters or 32 raw bytes; docs/mavlink-signing.md).
    #[arg(long, value_name = "PATH")]
    pub signing_key_file: Option<PathBuf>,
    /// Also show the manned aircraft of an ADS-B receiver: its SBS-1 output `HOST:PORT`
    /// (dump1090, readsb: port 30003; docs/adsb.md).
    #[arg(long, value_name = "HOST:PORT")]
    pub adsb: Option<String>,
    /// Send the confirmed tracks as Cursor-on-Target events to a TAK destination:
    /// `udp://HOST:PORT` (e.g. TAK's mesh group udp://239.2.3.1:6969), `tcp://HOST:PORT` (a TAK
    /// server's TCP input, 8087) (repeatable; turns `[cot]` on with these `cot.destinations`;
    /// docs/cot.md).
    #[arg(long = "cot", value_name = "DEST", value_parser = parse_cot_destination)]
    pub cot: Vec<String>,
    /// The encoding of the `--cot` events: xml (CoT 2.0) or protobuf (TAK protocol version 1);
    /// default `[cot]`'s (xml).
    #[arg(long, value_name = "xml|protobuf", value_parser = parse_cot_encoding, requires = "cot")]
    pub cot_encoding: Option<CotEncoding>,
    /// The map's online tiles: a URL template with {z}, {x}, {y} (`[map] tile_url`, e.g.
    /// `https://tile.openstreetmap.org/{z}/{x}/{y}.png`, credited to OpenStreetMap), shown before
    /// the offline tiles.
    #[arg(long, value_name = "URL")]
    pub tile_url: Option<String>,
    /// What the page credits for `--tile-url`'s tiles (`[map] attribution`).
    #[arg(long, value_name = "TEXT", requires = "tile_url")]
    pub tile_attribution: Option<String>,
    /// The map's offline tiles: this MBTiles file (`[map] mbtiles`) instead of the one the demo
    /// renders of its world on its first run and keeps in ~/.cache/harrier/tiles; `none`: no
    /// offline tiles.
    #[arg(long, value_name = "FILE|none")]
    pub mbtiles: Option<String>,
}

/// A `--cot` destination, checked as `cot.destinations` is (`tls://` needs the `[cot]` TLS
/// files, which the demo has no options for).
fn parse_cot_destination(s: &str) -> Result<String, String> {
    let d = CotDestination::parse(s)?;
    if d.transport == CotTransport::Tls {
        return Err(format!(
            "{s:?}: tls:// needs a CA and a client certificate (`[cot] tls_*`); use `harrier \
             serve` with a configuration file for TLS"
        ));
    }
    Ok(s.to_owned())
}

/// `xml` or `protobuf` of `--cot-encoding`.
fn parse_cot_encoding(s: &str) -> Result<CotEncoding, String> {
    match s {
        "xml" => Ok(CotEncoding::Xml),
        "protobuf" => Ok(CotEncoding::Protobuf),
        _ => Err(format!("{s:?}: expected xml or protobuf")),
    }
}

/// A `--fleet` entry.
fn parse_personality(s: &str) -> Result<Personality, String> {
    Personality::from_label(s)
        .ok_or_else(|| format!("{s:?}: expected px4-mc, ardupilot-mc, px4-fw or ardupilot-fw"))
}

/// `X,Y,R` of `--obstacle`.
pub(crate) fn parse_obstacle(s: &str) -> Result<ObstacleConfig, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: expected EAST,NORTH,RADIUS in metres: {e}"))?;
    match v[..] {
        [x_m, y_m, radius_m]
            if x_m.is_finite() && y_m.is_finite() && radius_m.is_finite() && radius_m > 0.0 =>
        {
            Ok(ObstacleConfig { x_m, y_m, radius_m })
        }
        _ => Err(format!(
            "{s:?}: expected EAST,NORTH,RADIUS with finite numbers and RADIUS > 0"
        )),
    }
}

/// What [`start`] runs (the command's arguments).
pub type DemoConfig = DemoArgs;

impl DemoConfig {
    /// The default demo with its API on `listen`, its GCS link on a free loopback port, no
    /// router and no offline map (`mbtiles` `none`: nothing rendered at start): for tests, where
    /// the well-known ports may be taken. A test of the map sets `mbtiles: None`.
    pub fn ephemeral(listen: SocketAddr) -> Self {
        Self {
            listen,
            gcs: "udpin:127.0.0.1:0".into(),
            router: Vec::new(),
            mbtiles: Some("none".into()),
            ..Self::default()
        }
    }
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            speedup: 1.0,
            seed: 1,
            vehicles: 3,
            fleet: Vec::new(),
            record: None,
            estimator: "cimm".into(),
            gcs: "udpin:127.0.0.1:14550".into(),
            router: vec![
                "udpin:127.0.0.1:14551".into(),
                "tcpin:127.0.0.1:5760".into(),
            ],
            no_assign: false,
            radius: 150.0,
            height: 300.0,
            obstacles: Vec::new(),
            signing_key_file: None,
            adsb: None,
            cot: Vec::new(),
            cot_encoding: None,
            tile_url: None,
            tile_attribution: None,
            mbtiles: None,
        }
    }
}

/// Why the demo could not start.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// An option is out of range.
    #[error("{0}")]
    Invalid(String),
    /// The demo's scenario does not build.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The live service did not start.
    #[error(transparent)]
    Live(#[from] LiveError),
    /// The simulated world did not start.
    #[error("simulator: {0}")]
    World(#[from] WorldError),
    /// No free loopback port for a Zenoh endpoint.
    #[error("no free port for the Zenoh session: {0}")]
    Port(std::io::Error),
    /// A blocking start or stop task failed.
    #[error("{0}")]
    Task(String),
    /// The offline map could not be rendered.
    #[error("offline map: {0}")]
    Tiles(String),
}

/// Slant range of the demo's cameras (m): every point of the road is within it from a station.
const CAMERA_RANGE_M: f64 = 2_500.0;
/// Speed of the first car (m/s).
const FIRST_CAR_SPEED: f64 = 5.0;
/// Speed of the first car with fixed wings in the fleet (m/s).
const MIXED_FLEET_CAR_SPEED: f64 = 1.5;
/// Where the second car starts on the road (m of arc length) and its speed (m/s).
const SECOND_CAR: (f64, f64) = (1_800.0, 7.0);

/// The demo's world: the `cimm-road` preset with a second, faster car ahead of the first on the
/// same road, and one camera slaved to each car (geolocated `position`, 10 m, 1 Hz).
pub fn scenario() -> Result<SimScenario, ScenarioError> {
    scenario_with_car(FIRST_CAR_SPEED)
}

/// [`scenario`] with the first car at `first_car_speed` m/s.
fn scenario_with_car(first_car_speed: f64) -> Result<SimScenario, ScenarioError> {
    let mut s = SimScenario::load("cimm-road")?;
    s.name = "demo".into();
    s.description = "harrier demo: two cars on the cimm-road road, UAVs on station along it, \
                     a camera slaved to each car on every UAV."
        .into();
    // The first car slower than the preset's 10 m/s: the multirotors (15 m/s at most) keep
    // their standoff circle around it with speed to spare for the phase spacing.
    if let TargetMotion::Road { speed_mps, .. } = &mut s.targets[0].motion {
        *speed_mps = first_car_speed;
    }
    let mut second = s.targets[0].clone();
    second.id = "tgt2".into();
    if let TargetMotion::Road {
        start_m, speed_mps, ..
    } = &mut second.motion
    {
        (*start_m, *speed_mps) = SECOND_CAR;
    }
    s.targets.push(second);
    let mut cam2 = s.sensors[0].clone();
    cam2.id = "cam2".into();
    if let SensorType::Camera { pointing, .. } = &mut cam2.model {
        *pointing = harrier_sim::setup::Pointing::Track { target: 1 };
    }
    s.sensors.push(cam2);
    for c in &mut s.sensors {
        c.max_range_m = CAMERA_RANGE_M;
    }
    Ok(s)
}

/// A Zenoh TCP endpoint on a loopback port that is free now (Zenoh's stable API does not report
/// the port it bound for port 0).
fn free_loopback_endpoint() -> Result<String, DemoError> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map_err(DemoError::Port)?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

/// The running demo. Stop it with [`Demo::stop`].
#[derive(Debug)]
pub struct Demo {
    server: LiveServer,
    world: SimWorld,
    endpoints: Vec<String>,
    /// Assigns the UAVs once they are heard and every car has a confirmed track, and again when
    /// the tracker deletes that track ([`Assigner::keep`]).
    assigner: Option<tokio::task::JoinHandle<()>>,
}

impl Demo {
    /// The live service.
    pub fn server(&self) -> &LiveServer {
        &self.server
    }
    /// The simulated world (vehicles, their MAVLink addresses, publication counters).
    pub fn world(&self) -> &SimWorld {
        &self.world
    }
    /// The Zenoh endpoints to connect to, to see everything published: the service's session and
    /// the simulator's (peers do not forward each other's data).
    pub fn zenoh_endpoints(&self) -> &[String] {
        &self.endpoints
    }

    /// Stops the service, then the simulated world.
    pub async fn stop(self) {
        if let Some(a) = self.assigner {
            a.abort();
        }
        self.server.shutdown().await;
        let world = self.world;
        if let Err(e) = tokio::task::spawn_blocking(move || world.stop()).await {
            tracing::warn!("stopping the simulator: {e}");
        }
    }
}

/// The live service's configuration of the demo (`scenario`'s frame, roads and motion models,
/// `config`'s options); the Zenoh endpoints and the offline map are `start`'s.
pub fn server_config(config: &DemoConfig, scenario: &SimScenario) -> Config {
    let mut server_config = Config::default();
    server_config.frame.origin = scenario.origin;
    server_config.frame.plane_z = scenario.plane_z();
    server_config.api.listen = config.listen;
    server_config
        .tracker
        .estimator
        .clone_from(&config.estimator);
    server_config.tracker.roads.clone_from(&scenario.roads);
    server_config
        .guidance
        .obstacles
        .clone_from(&config.obstacles);
    if let Some(motion) = &scenario.estimator.motion {
        server_config.tracker.motion = motion.clone();
    }
    server_config.zenoh.connect = Vec::new();
    if config.speedup != 1.0 {
        // The simulator's `time_unix` runs `speedup` times faster than any real clock.
        server_config.clock.real_time = false;
    }
    if let Some(path) = &config.record {
        server_config.recorder.path = path.display().to_string();
    }
    if let Some(address) = &config.adsb {
        server_config.adsb.enabled = true;
        server_config.adsb.address.clone_from(address);
    }
    if !config.cot.is_empty() {
        server_config.cot.enabled = true;
        server_config.cot.destinations.clone_from(&config.cot);
    }
    if let Some(encoding) = config.cot_encoding {
        server_config.cot.encoding = encoding;
    }
    server_config.mavlink.gcs = vec![config.gcs.clone()];
    server_config.mavlink.router = config
        .router
        .iter()
        .filter(|r| r.as_str() != "none")
        .cloned()
        .collect();
    if let Some(url) = &config.tile_url {
        server_config.map.tile_url.clone_from(url);
    }
    if let Some(text) = &config.tile_attribution {
        server_config.map.attribution.clone_from(text);
    }
    if let Some(key_file) = &config.signing_key_file {
        server_config.mavlink.signing = SigningConfig {
            mode: "signed_only".into(),
            key_file: key_file.display().to_string(),
            ..SigningConfig::default()
        };
    }
    // Multirotors around a 5 m/s car: a relative speed that leaves room under their 15 m/s; with
    // fixed wings, 12.5 m/s around a 1.5 m/s car (11–14 m/s over the ground).
    server_config.guidance.speed_m_s = car_and_standoff_speeds(config).1;
    server_config
}

/// The first car's speed and the standoff speed (m/s): slower around a slower car when the
/// fleet has fixed wings.
fn car_and_standoff_speeds(config: &DemoConfig) -> (f64, f64) {
    if config
        .personalities()
        .iter()
        .any(|p| p.frame == Frame::FixedWing)
    {
        (MIXED_FLEET_CAR_SPEED, MIXED_FLEET_SPEED_M_S)
    } else {
        (FIRST_CAR_SPEED, DEMO_SPEED_M_S)
    }
}

/// Starts the live service and the simulated world; returns once the API accepts requests and
/// the simulator publishes.
pub async fn start(config: &DemoConfig) -> Result<Demo, DemoError> {
    if !(config.speedup.is_finite() && config.speedup > 0.0 && config.speedup <= 100.0) {
        return Err(DemoError::Invalid(format!(
            "--speedup must be in (0, 100], got {}",
            config.speedup
        )));
    }
    if config.vehicles == 0 {
        return Err(DemoError::Invalid("--vehicles must be ≥ 1".into()));
    }
    let fleet = config.personalities();
    if fleet.len() > 255 {
        return Err(DemoError::Invalid("--fleet: at most 255 vehicles".into()));
    }
    let scenario = scenario_with_car(car_and_standoff_speeds(config).0)?;
    let server_endpoint = free_loopback_endpoint()?;
    let sim_endpoint = free_loopback_endpoint()?;

    let mut server_config = server_config(config, &scenario);
    server_config.zenoh.listen = vec![server_endpoint.clone()];
    server_config.map.mbtiles = match config.mbtiles.as_deref() {
        Some("none") => String::new(),
        Some(file) => file.to_owned(),
        None => crate::offline_map::offline_tiles(&server_config)
            .await
            .map_err(DemoError::Tiles)?
            .display()
            .to_string(),
    };
    let signing = server_config
        .mavlink
        .signing
        .resolve()
        .map_err(|e| DemoError::Invalid(e.to_string()))?;
    if !server_config.clock.real_time {
        tracing::info!(
            speedup = config.speedup,
            "clock.real_time = false: simulated time runs faster than the server's clock"
        );
    }
    let server = harrier_server::start(&server_config).await?;
    let gcs = server
        .link()
        .and_then(|l| l.gcs().next().map(|e| e.addr()))
        .ok_or_else(|| DemoError::Invalid("the demo needs a GCS link".into()))?;
    let gcs = if gcs.ip().is_unspecified() {
        SocketAddr::from(([127, 0, 0, 1], gcs.port()))
    } else {
        gcs
    };

    let mut world_config = WorldConfig::new(SensorLoopConfig {
        scenario: scenario.clone(),
        seed: config.seed,
        speedup: config.speedup,
        truth_hz: 10.0,
        clock: Default::default(),
    });
    world_config.vehicles = (1..=255)
        .zip(&fleet)
        .map(|(id, p)| WorldVehicle::grounded(id).with_personality(*p))
        .collect();
    world_config.zenoh.connect = vec![server_endpoint.clone()];
    world_config.zenoh.listen = vec![sim_endpoint.clone()];
    world_config.gcs = Some(gcs);
    world_config.signing = signing;
    let world = match tokio::task::spawn_blocking(move || SimWorld::start(&world_config)).await {
        Ok(Ok(w)) => w,
        Ok(Err(e)) => {
            server.shutdown().await;
            return Err(e.into());
        }
        Err(e) => {
            server.shutdown().await;
            return Err(DemoError::Task(format!("starting the simulator: {e}")));
        }
    };
    tracing::info!(
        vehicles = fleet.len(),
        fleet = %fleet.iter().map(|p| p.label()).collect::<Vec<_>>().join(","),
        speedup = config.speedup,
        seed = config.seed,
        "simulated world started"
    );
    let assigner = match (config.no_assign, server.guidance(), server.link()) {
        (false, Some(guidance), Some(link)) => Some(tokio::spawn(
            Assigner {
                guidance: guidance.clone(),
                link: link.clone(),
                snapshot: server.snapshot(),
                vehicles: fleet.len() as u8,
                cars: scenario.targets.len(),
                radius: config.radius,
                height: config.height,
            }
            .keep(),
        )),
        _ => None,
    };
    Ok(Demo {
        server,
        world,
        endpoints: vec![server_endpoint, sim_endpoint],
        assigner,
    })
}

/// Relative speed of the demo's standoff law (m/s).
const DEMO_SPEED_M_S: f64 = 5.0;
/// The same with fixed wings in the fleet (m/s).
const MIXED_FLEET_SPEED_M_S: f64 = 12.5;

impl DemoConfig {
    /// The fleet: `--fleet`, else `--vehicles` PX4 multirotors.
    pub fn personalities(&self) -> Vec<Personality> {
        if self.fleet.is_empty() {
            vec![Personality::PX4_MULTIROTOR; usize::from(self.vehicles)]
        } else {
            self.fleet.clone()
        }
    }
}

/// Runs the demo until Ctrl-C: structured logs on stderr (`RUST_LOG`), the URLs on stdout.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    use std::io::Write as _;
    crate::init_logging("info,zenoh=warn");
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let demo = start(args).await?;
        let addr = demo.server().local_addr();
        let mavlink: Vec<String> = demo
            .world()
            .mavlink_addrs()
            .iter()
            .map(|(id, a)| format!("{id}: udp {a}"))
            .collect();
        let token = match demo.server().token() {
            (token, harrier_server::TokenSource::Generated) => token.to_owned(),
            (_, source) => format!("(from {source:?})"),
        };
        let (gcs, router) = demo
            .server()
            .link()
            .map_or_else(Default::default, harrier_server::gcs::GcsLink::describe);
        let cot = if args.cot.is_empty() {
            String::new()
        } else {
            let encoding = match args.cot_encoding.unwrap_or(CotConfig::default().encoding) {
                CotEncoding::Xml => "xml",
                CotEncoding::Protobuf => "protobuf",
            };
            format!("\n  CoT        {encoding} to {}", args.cot.join(", "))
        };
        let _ = writeln!(
            std::io::stdout().lock(),
            "harrier demo: ready\n  dashboard  http://{addr}/\n  API        http://{addr}/api/v1 \
             (e.g. /api/v1/tracks)\n  API token  {token} (`Authorization: Bearer <token>` on \
             mutating requests)\n  zenoh      {}\n  UAVs       {}\n  MAVLink    GCS link {gcs}; \
             router (QGroundControl, MAVProxy, MAVSDK) {router}{cot}\nPress Ctrl-C to stop.",
            demo.zenoh_endpoints().join(", "),
            mavlink.join(", ")
        );
        tokio::signal::ctrl_c().await?;
        tracing::info!("interrupted: shutting down");
        demo.stop().await;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_link::autopilot::Autopilot;

    /// `--cot` takes what `cot.destinations` takes (not TLS, which needs files), and says why
    /// not; `--cot-encoding` xml or protobuf.
    #[test]
    fn fleet_entries_name_an_autopilot_and_an_airframe() {
        let p = parse_personality("ardupilot-fw").expect("ArduPlane");
        assert_eq!(p, Personality::new(Autopilot::ArduPilot, Frame::FixedWing));
        let e = parse_personality("px4-vtol").expect_err("no VTOL");
        assert!(
            e.contains("px4-mc, ardupilot-mc, px4-fw or ardupilot-fw"),
            "{e}"
        );
        let d = DemoConfig::default();
        assert_eq!(d.personalities(), vec![Personality::PX4_MULTIROTOR; 3]);
    }

    #[test]
    fn cot_options_check_their_values() {
        for good in [
            "udp://127.0.0.1:6969",
            "udp://239.2.3.1:6969",
            "tcp://takserver:8087",
        ] {
            assert_eq!(parse_cot_destination(good).as_deref(), Ok(good));
        }
        for (bad, why) in [
            ("127.0.0.1:6969", "scheme://host:port"),
            ("udp://127.0.0.1", "no port"),
            ("tcp://h:0", "1–65535"),
            ("http://h:80", "unknown scheme"),
            ("tls://takserver:8089", "tls_"),
        ] {
            let e = parse_cot_destination(bad).expect_err(bad);
            assert!(e.contains(why), "{bad}: {e}");
        }
        assert_eq!(parse_cot_encoding("xml"), Ok(CotEncoding::Xml));
        assert_eq!(parse_cot_encoding("protobuf"), Ok(CotEncoding::Protobuf));
        assert!(parse_cot_encoding("json").is_err());
    }

    /// The demo's world: two cars on one road that never meet (the slower one behind), a
    /// camera slaved to each.
    #[test]
    fn two_cars_that_never_meet() {
        let s = scenario().expect("demo scenario");
        assert_eq!(s.targets.len(), 2);
        assert_eq!(s.sensors.len(), 2);
        let road = |t: &harrier_sim::setup::TargetSpec| match t.motion {
            TargetMotion::Road {
                start_m, speed_mps, ..
            } => (start_m, speed_mps),
            _ => panic!("not on the road"),
        };
        let (a, b) = (road(&s.targets[0]), road(&s.targets[1]));
        assert!(a.0 < b.0 && a.1 < b.1, "{a:?} {b:?}");
    }
}
