//! `harrier demo`: the live service, an in-process Zenoh peer and simulated UAVs in one process.
//!
//! [`start`] opens the live service ([`crate::live::start`]) with its Zenoh session listening on a
//! free loopback port, then starts harrier-sim's world ([`SimWorld`]) whose session connects to
//! it: the `cimm-road` preset with a second car on the road and a camera slaved to each car on
//! every UAV, the UAVs launched to stations spread along the road, 300 m up. The service tracks
//! with the preset's road and motion models (CIMM by default). [`run`] is the command: it starts
//! the demo, prints where to point a browser and waits for Ctrl-C.

use std::net::SocketAddr;
use std::path::PathBuf;

use harrier_core::scenario::Segment;
use harrier_sim::embedded::{SimWorld, WorldConfig, WorldError, WorldVehicle};
use harrier_sim::live::LiveConfig;
use harrier_sim::setup::{ScenarioError, SensorModel, SimScenario, TargetMotion};

use crate::live::config::Config;
use crate::live::{self, LiveError, LiveServer};

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
    /// Number of simulated UAVs (MAVLink system ids 1…N), spread along the road.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..))]
    pub vehicles: u8,
    /// Record the session into this SQLite file (created if missing; `harrier sessions` reads
    /// it).
    #[arg(long, value_name = "SQLITE")]
    pub record: Option<PathBuf>,
    /// Track engine: ekf, cdkf, imm or cimm (road-constrained IMM on the demo's road).
    #[arg(long, short, default_value = "cimm")]
    pub estimator: String,
}

/// What [`start`] runs (the command's arguments).
pub type DemoConfig = DemoArgs;

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            speedup: 1.0,
            seed: 1,
            vehicles: 3,
            record: None,
            estimator: "cimm".into(),
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
}

/// Height of the UAVs' stations above the ground (m): the preset's orbit height.
const STATION_HEIGHT_M: f64 = 300.0;
/// Slant range of the demo's cameras (m): every point of the road is within it from a station.
const CAMERA_RANGE_M: f64 = 2_500.0;
/// Where the second car starts on the road (m of arc length) and its speed (m/s).
const SECOND_CAR: (f64, f64) = (1_800.0, 7.0);

/// The demo's world: the `cimm-road` preset with a second, slower car ahead of the first on the
/// same road, and one camera slaved to each car (geolocated `position`, 10 m, 1 Hz).
pub fn scenario() -> Result<SimScenario, ScenarioError> {
    let mut s = SimScenario::load("cimm-road")?;
    s.name = "demo".into();
    s.description = "harrier demo: two cars on the cimm-road road, UAVs on station along it, \
                     a camera slaved to each car on every UAV."
        .into();
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
    if let SensorModel::Camera { pointing, .. } = &mut cam2.model {
        *pointing = harrier_sim::setup::Pointing::Track { target: 1 };
    }
    s.sensors.push(cam2);
    for c in &mut s.sensors {
        c.max_range_m = CAMERA_RANGE_M;
    }
    Ok(s)
}

/// `n` stations spread evenly along the scenario's first road (on the polyline through its
/// segments' ends), at [`STATION_HEIGHT_M`]; above the origin when there is no road.
pub fn stations(scenario: &SimScenario, n: u8) -> Vec<[f64; 3]> {
    let mut points: Vec<[f64; 2]> = Vec::new();
    for seg in scenario.roads.first().map_or(&[][..], |r| &r.segments) {
        let (start, end) = match seg {
            Segment::Line { start, end } | Segment::Arc { start, end, .. } => (*start, *end),
        };
        if points.is_empty() {
            points.push(start);
        }
        points.push(end);
    }
    let legs: Vec<f64> = points
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .collect();
    let total: f64 = legs.iter().sum();
    (0..n)
        .map(|k| {
            let mut s = total * (f64::from(k) + 0.5) / f64::from(n);
            for (w, len) in points.windows(2).zip(&legs) {
                if s <= *len && *len > 0.0 {
                    let f = s / len;
                    let (a, b) = (w[0], w[1]);
                    return [
                        a[0] + f * (b[0] - a[0]),
                        a[1] + f * (b[1] - a[1]),
                        STATION_HEIGHT_M,
                    ];
                }
                s -= len;
            }
            [0.0, 0.0, STATION_HEIGHT_M]
        })
        .collect()
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
        self.server.shutdown().await;
        let world = self.world;
        if let Err(e) = tokio::task::spawn_blocking(move || world.stop()).await {
            tracing::warn!("stopping the simulator: {e}");
        }
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
    let scenario = scenario()?;
    let server_endpoint = free_loopback_endpoint()?;
    let sim_endpoint = free_loopback_endpoint()?;

    let mut server_config = Config::default();
    server_config.frame.origin = scenario.origin;
    server_config.frame.plane_z = scenario.plane_z();
    server_config.api.listen = config.listen;
    server_config
        .tracker
        .estimator
        .clone_from(&config.estimator);
    server_config.tracker.roads.clone_from(&scenario.roads);
    if let Some(motion) = &scenario.estimator.motion {
        server_config.tracker.motion = motion.clone();
    }
    server_config.zenoh.listen = vec![server_endpoint.clone()];
    server_config.zenoh.connect = Vec::new();
    if let Some(path) = &config.record {
        server_config.recorder.path = path.display().to_string();
    }
    let server = live::start(&server_config).await?;

    let mut world_config = WorldConfig::new(LiveConfig {
        scenario: scenario.clone(),
        seed: config.seed,
        speedup: config.speedup,
        truth_hz: 10.0,
    });
    world_config.vehicles = (1..=config.vehicles)
        .zip(stations(&scenario, config.vehicles))
        .map(|(id, station)| WorldVehicle::at(id, station))
        .collect();
    world_config.zenoh.connect = vec![server_endpoint.clone()];
    world_config.zenoh.listen = vec![sim_endpoint.clone()];
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
        vehicles = config.vehicles,
        speedup = config.speedup,
        seed = config.seed,
        "simulated world started"
    );
    Ok(Demo {
        server,
        world,
        endpoints: vec![server_endpoint, sim_endpoint],
    })
}

/// Runs the demo until Ctrl-C: structured logs on stderr (`RUST_LOG`), the URLs on stdout.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    use std::io::Write as _;
    use tracing_subscriber::EnvFilter;
    tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info,zenoh=warn")),
        )
        .with_writer(std::io::stderr)
        .init();
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
            (token, live::TokenSource::Generated) => token.to_owned(),
            (_, source) => format!("(from {source:?})"),
        };
        let _ = writeln!(
            std::io::stdout().lock(),
            "harrier demo: ready\n  dashboard  http://{addr}/\n  API        http://{addr}/api/v1 \
             (e.g. /api/v1/tracks)\n  API token  {token} (`Authorization: Bearer <token>` on \
             mutating requests)\n  zenoh      {}\n  UAVs       {}\nPress Ctrl-C to stop.",
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

    /// The stations are spread along the road, and from them the cameras reach every segment end
    /// of it.
    #[test]
    fn stations_cover_the_road() {
        let s = scenario().expect("demo scenario");
        assert_eq!(s.targets.len(), 2);
        let st = stations(&s, 3);
        assert_eq!(st.len(), 3);
        for w in st.windows(2) {
            assert!(
                (w[0][0] - w[1][0]).hypot(w[0][1] - w[1][1]) > 1000.0,
                "{st:?}"
            );
        }
        for seg in &s.roads[0].segments {
            let (Segment::Line { end, .. } | Segment::Arc { end, .. }) = seg;
            let nearest = st
                .iter()
                .map(|p| (p[0] - end[0]).hypot(p[1] - end[1]).hypot(p[2]))
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < CAMERA_RANGE_M, "{end:?} is {nearest} m away");
        }
        assert_eq!(stations(&s, 1).len(), 1);
    }
}
