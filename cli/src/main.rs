//! `harrier`: the Harrier ground-station command line.
//!
//! ```not_rust
//! harrier estimators
//! harrier serve --config harrier.toml --listen 127.0.0.1:8080
//! harrier replay ../shared/scenarios/radar_bias_none --estimator cdkf --out /tmp/estimates.jsonl
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// `println!` that does not panic when stdout is closed (e.g. piped into `head`): output that
/// cannot be written is dropped.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}
use harrier_engine::Params;
use harrier_engine::registry::{ASSOCIATORS, ESTIMATORS, TRACK_FILTERS};
use harrier_tools::guidance_sim;
use harrier_tools::replay;

/// Harrier: ground-control station for UAV target tracking.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run an estimator over a gcs-scenario/1 directory and write estimates.jsonl.
    Replay {
        /// Scenario directory (scenario.json, measurements.jsonl, optional truth.csv).
        scenario: PathBuf,
        /// Replay estimator name (see `harrier estimators`).
        #[arg(long, short)]
        estimator: String,
        /// Output file.
        #[arg(long, short, default_value = "estimates.jsonl")]
        out: PathBuf,
        /// Estimator parameter, `name=value` (repeatable).
        #[arg(long = "param", short = 'p', value_name = "NAME=VALUE")]
        params: Vec<String>,
        /// Print the score as JSON instead of a summary.
        #[arg(long)]
        json: bool,
        /// With `-e tracker`: the filter of each track (`harrier estimators`; default ekf).
        #[arg(long)]
        track_filter: Option<String>,
        /// With `-e tracker`: the associator (`gnn`, `jipda`, `mht`; default gnn).
        #[arg(long)]
        associator: Option<String>,
        /// With `-e tracker`: estimate the biases of the sensors with a `bias` block jointly
        /// with the tracks, as the live service's `[registration]` does; the estimate lines get
        /// `bias_est` (FORMAT-REGISTRATION.md).
        #[arg(long)]
        register: bool,
    },
    /// Run a closed-loop guidance scenario (see GUIDANCE.md) and print its figures.
    GuidanceSim(GuidanceSimArgs),
    /// Write a seeded multi-target scenario: crossing targets, Pd 0.9, clutter (FORMAT-MULTI.md);
    /// or, with --shape, close groups of turning ground targets.
    GenMulti {
        /// Output directory (created if missing).
        dir: PathBuf,
        /// RNG seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Close groups of turning ground targets instead: `crossing`, `parallel` (30–90 m
        /// apart), `opposing`, `mixed` (four groups, 10 clutter detections a scan) or `dense`
        /// (mixed, 50 a scan).
        #[arg(long)]
        shape: Option<String>,
    },
    /// Write a seeded sensor-registration scenario: a ground target, a biased radar, two UAVs'
    /// cameras with outages, bias truth and references (FORMAT-REGISTRATION.md).
    GenRegistration {
        /// Output directory (created if missing).
        dir: PathBuf,
        /// RNG seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Which biases: none, constant, gauss-markov, mounting, time-offset, radar-reference,
        /// radar-alone.
        #[arg(long, default_value = "constant")]
        case: String,
        /// What the scenario tells the estimator: deployment (every sensor with Harrier's
        /// default bias model), told-model (the true bias models), told-bias (the biases taken
        /// out of the measurements).
        #[arg(long, default_value = "deployment")]
        variant: String,
        /// Length of the run, s (one scan per second).
        #[arg(long, default_value_t = 600.0)]
        duration: f64,
    },
    /// Compare the multi-target tracker's associators on generated close groups (GOSPA,
    /// swaps, id switches, breaks, false tracks, confirmation delay, time per scan), or score
    /// an estimates file.
    TrackEval(harrier_tools::track_eval::EvalArgs),
    /// Run the live tracking service: detections from Zenoh in, tracks over HTTP (`/api/v1`).
    Serve(ServeArgs),
    /// Run the demo: the service, an in-process Zenoh peer and simulated UAVs, in one process.
    Demo(harrier_cli::demo::DemoArgs),
    /// Build or inspect the MBTiles files of the dashboard's map (offline tiles of a
    /// deployment's roads and no-fly areas).
    Tiles(harrier_cli::tiles::TilesArgs),
    /// List recorded sessions, or export one as a gcs-scenario/1 directory.
    Sessions(harrier_tools::sessions::SessionsArgs),
    /// Load-test the live service: simulated vehicles' detections in, WebSocket and REST clients
    /// out; prints rates, latencies and memory (BENCHMARKS.md).
    Bench(harrier_bench::BenchArgs),
    /// List the replay estimators and the live tracker's track filters, one line each.
    Estimators {
        /// Also list each one's parameter names.
        #[arg(long)]
        params: bool,
    },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap would suggest `--cot`, the nearest spelling; the port is in `--listen`.
            if e.kind() == clap::error::ErrorKind::UnknownArgument
                && std::env::args().any(|a| a == "--port" || a.starts_with("--port="))
            {
                eprintln!(
                    "error: unexpected argument '--port': the port is part of the address, \
                     `--listen ADDR:PORT` (e.g. `--listen 127.0.0.1:8081`; port 0: any free \
                     port)\n\nFor more information, try '--help'."
                );
                return ExitCode::from(2);
            }
            e.exit()
        }
    };
    match cli.command {
        Command::Serve(args) => match run_serve(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier serve: error: {}", harrier_cli::error_message(&e));
                ExitCode::from(2)
            }
        },
        Command::Demo(args) => match harrier_cli::demo::run(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier demo: error: {}", harrier_cli::error_message(&e));
                ExitCode::from(2)
            }
        },
        Command::Bench(args) => match run_bench(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier bench: error: {}", harrier_cli::error_message(&e));
                ExitCode::from(2)
            }
        },
        Command::Tiles(args) => match harrier_cli::tiles::run(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier tiles: error: {}", harrier_cli::error_message(&e));
                ExitCode::from(2)
            }
        },
        Command::Sessions(args) => match harrier_tools::sessions::run(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!(
                    "harrier sessions: error: {}",
                    harrier_cli::error_message(&e)
                );
                ExitCode::from(2)
            }
        },
        Command::Estimators { params } => {
            out!("Replay estimators (harrier replay -e NAME, --param NAME=VALUE):");
            for e in ESTIMATORS {
                out!("{:<14} {}", e.name, e.summary);
                for (p, d) in e.params.iter().filter(|_| params) {
                    out!("{:<14}   --param {p}=…  {d}", "");
                }
            }
            out!("");
            out!(
                "Track filters of the live tracker ([tracker] estimator and params, \
                 PUT /api/v1/estimator), not the replay estimators of the same names:"
            );
            for f in TRACK_FILTERS {
                out!("{:<14} {}", f.name, f.summary);
                for (p, d) in f.params.iter().filter(|_| params) {
                    out!("{:<14}   {p} = …  {d}", "");
                }
            }
            out!("");
            out!(
                "Associators of the live tracker (harrier replay -e tracker --associator NAME), \
                 with any track filter:"
            );
            for a in ASSOCIATORS {
                out!("{:<14} {}", a.name, a.summary);
                for (p, d) in a.params.iter().filter(|_| params) {
                    out!("{:<14}   {p} = …  {d}", "");
                }
            }
            ExitCode::SUCCESS
        }
        Command::GenMulti { dir, seed, shape } => {
            let written = match shape {
                None => harrier_tools::gen_multi::write(&dir, seed),
                Some(s) => harrier_tools::gen_multi::write_groups(&dir, seed, &s),
            };
            match written {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("harrier gen-multi: error: {e:#}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::TrackEval(args) => match harrier_tools::track_eval::run(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier track-eval: error: {e:#}");
                ExitCode::from(2)
            }
        },
        Command::GenRegistration {
            dir,
            seed,
            case,
            variant,
            duration,
        } => {
            let written = harrier_tools::gen_registration::config(&case, &variant, duration)
                .and_then(|cfg| harrier_tools::gen_registration::write(&dir, seed, &cfg));
            match written {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("harrier gen-registration: error: {e:#}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::GuidanceSim(args) => match run_guidance_sim(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier guidance-sim: error: {e}");
                ExitCode::from(2)
            }
        },
        Command::Replay {
            scenario,
            estimator,
            out,
            params,
            json,
            track_filter,
            associator,
            register,
        } => match run_replay(
            &scenario,
            &estimator,
            (track_filter, associator, register),
            &out,
            &params,
            json,
        ) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier replay: error: {e}");
                ExitCode::from(e.exit_code())
            }
        },
    }
}

/// Arguments of `harrier serve`; each flag overrides its key in the configuration file.
#[derive(Debug, clap::Args)]
struct ServeArgs {
    /// TOML configuration (see harrier.example.toml); without it, the defaults.
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Address of the HTTP API (`api.listen`; default 127.0.0.1:8080, port 0: any free port).
    #[arg(long)]
    listen: Option<std::net::SocketAddr>,
    /// Zenoh session mode, peer or client (`zenoh.mode`; default peer).
    #[arg(long, value_name = "MODE")]
    zenoh_mode: Option<String>,
    /// Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable; replaces
    /// `zenoh.listen`, default tcp/127.0.0.1:7447).
    #[arg(long, value_name = "ENDPOINT")]
    zenoh_listen: Vec<String>,
    /// Zenoh endpoint to connect to, e.g. a router's tcp/10.0.0.1:7447 (repeatable; replaces
    /// `zenoh.connect`).
    #[arg(long, value_name = "ENDPOINT")]
    zenoh_connect: Vec<String>,
    /// Track filter: ekf, cdkf, imm or cimm (`tracker.estimator`; default ekf).
    #[arg(long, short)]
    estimator: Option<String>,
    /// Record the session into this SQLite file (`recorder.path`; see RECORDING.md). If it
    /// cannot be opened (read-only, full), the service logs why and tracks without recording.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// MAVLink GCS endpoint the vehicles send to, e.g. udpin:0.0.0.0:14550 (repeatable; replaces
    /// `mavlink.gcs`; `none`: no MAVLink link).
    #[arg(long, value_name = "ENDPOINT")]
    gcs: Vec<String>,
    /// MAVLink router endpoint for QGroundControl, MAVProxy or MAVSDK, e.g. tcpin:0.0.0.0:5760
    /// (repeatable; replaces `mavlink.router`; `none`: no router).
    #[arg(long, value_name = "ENDPOINT")]
    router: Vec<String>,
    /// Track the manned aircraft of an ADS-B receiver's output, e.g. SBS-1 on 127.0.0.1:30003
    /// (turns `[adsb]` on with this `adsb.address`; docs/adsb.md).
    #[arg(long, value_name = "HOST:PORT")]
    adsb: Option<String>,
    /// What the ADS-B receiver's output is: sbs (SBS-1 text, port 30003) or beast (Beast
    /// binary, port 30005) (`adsb.format`; default sbs).
    #[arg(long, value_name = "FORMAT")]
    adsb_format: Option<harrier_server::config::AdsbFormat>,
}

/// A repeatable endpoint option: empty keeps the configuration, `none` clears it.
fn endpoints(given: &[String], configured: &mut Vec<String>) {
    if !given.is_empty() {
        *configured = given.iter().filter(|e| *e != "none").cloned().collect();
    }
}

/// `harrier bench`, with its own log filter (the service it starts logs only warnings).
fn run_bench(args: &harrier_bench::BenchArgs) -> anyhow::Result<()> {
    harrier_cli::init_logging("warn,zenoh=error");
    harrier_bench::run(args)
}

fn run_serve(a: &ServeArgs) -> anyhow::Result<()> {
    use harrier_server::config::Config;
    harrier_cli::init_logging("info,zenoh=warn");
    let mut config = match &a.config {
        Some(path) => Config::load(path)?,
        None => Config::default(),
    };
    if let Some(listen) = a.listen {
        config.api.listen = listen;
    }
    if let Some(mode) = &a.zenoh_mode {
        config.zenoh.mode.clone_from(mode);
    }
    if !a.zenoh_listen.is_empty() {
        config.zenoh.listen.clone_from(&a.zenoh_listen);
    }
    if !a.zenoh_connect.is_empty() {
        config.zenoh.connect.clone_from(&a.zenoh_connect);
    }
    if let Some(e) = &a.estimator {
        config.tracker.estimator.clone_from(e);
    }
    if let Some(path) = &a.record {
        config.recorder.path = path.display().to_string();
    }
    endpoints(&a.gcs, &mut config.mavlink.gcs);
    endpoints(&a.router, &mut config.mavlink.router);
    if let Some(address) = &a.adsb {
        config.adsb.enabled = true;
        config.adsb.address.clone_from(address);
    }
    if let Some(format) = a.adsb_format {
        config.adsb.format = format;
    }
    config.check()?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let server = harrier_server::start(&config).await?;
        if let Some((gcs, router)) = server.link().map(harrier_server::gcs::GcsLink::describe) {
            eprintln!("harrier serve: MAVLink GCS link {gcs}; router {router}");
        }
        eprintln!(
            "harrier serve: ready: http://{}/api/v1 (estimator {}, zenoh {} listen {:?} connect {:?})",
            server.local_addr(),
            config.tracker.estimator,
            config.zenoh.mode,
            config.zenoh.listen,
            config.zenoh.connect
        );
        match server.token() {
            (token, harrier_server::TokenSource::Generated) => eprintln!(
                "harrier serve: API token (mutating requests need `Authorization: Bearer <token>`): {token}"
            ),
            (_, source) => eprintln!("harrier serve: API token from {source:?}"),
        }
        tokio::signal::ctrl_c().await?;
        tracing::info!("interrupted: shutting down");
        server.shutdown().await;
        Ok(())
    })
}

/// Arguments of `harrier guidance-sim`.
#[derive(Debug, clap::Args)]
struct GuidanceSimArgs {
    /// Built-in case: cimm-static, cimm-moving, three-static, three-moving, bot-formation,
    /// bot-observability.
    #[arg(long, default_value = "cimm-static")]
    case: String,
    /// Standoff law: togvf or lgvf.
    #[arg(long, default_value = "togvf")]
    law: String,
    /// What the guidance sees of the target: truth, or a registry estimator (`harrier
    /// estimators`) on simulated camera measurements, e.g. cimm (road-constrained IMM) or kf
    /// (Kalman filter); default cimm for moving targets, truth for static ones.
    #[arg(long)]
    estimator: Option<String>,
    /// Time step (s).
    #[arg(long, default_value_t = 0.1)]
    dt: f64,
    /// Duration (s); default per case.
    #[arg(long)]
    duration: Option<f64>,
    /// RNG seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Trajectory file (.csv or .jsonl).
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// SVG picture of the paths, circle and obstacles.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

fn run_guidance_sim(a: &GuidanceSimArgs) -> Result<(), guidance_sim::SimError> {
    use guidance_sim::{Case, LawKind, SimConfig};
    let cfg = SimConfig {
        case: Case::parse(&a.case)?,
        law: LawKind::parse(&a.law)?,
        estimator: a.estimator.clone(),
        dt: a.dt,
        duration: a.duration,
        seed: a.seed,
    };
    let result = guidance_sim::run(&cfg)?;
    if let Some(out) = &a.out {
        guidance_sim::write_trajectories(out, &result.trajectories)?;
    }
    if let Some(plot) = &a.plot {
        guidance_sim::plot_svg(plot, &result, 600)?;
    }
    if a.json {
        out!(
            "{}",
            serde_json::to_string_pretty(&result.summary).unwrap_or_default()
        );
    } else {
        for line in guidance_sim::summary_lines(&result.summary) {
            out!("{line}");
        }
    }
    Ok(())
}

fn run_replay(
    dir: &std::path::Path,
    estimator: &str,
    (track_filter, associator, register): (Option<String>, Option<String>, bool),
    out: &std::path::Path,
    params: &[String],
    json: bool,
) -> Result<(), replay::ReplayError> {
    let params = Params::parse(params).map_err(|e| replay::ReplayError::Setup(e.to_string()))?;
    let data = replay::load(dir)?;
    let report = if track_filter.is_some() || associator.is_some() || register {
        if estimator != "tracker" {
            return Err(replay::ReplayError::Setup(
                "--track-filter, --associator and --register go with -e tracker".into(),
            ));
        }
        let choice = replay::TrackerChoice {
            filter: track_filter.unwrap_or_else(|| "ekf".into()),
            associator: associator.unwrap_or_else(|| "gnn".into()),
            register,
        };
        replay::run_tracker(&data, &choice, &params)?
    } else {
        replay::run(&data, estimator, &params)?
    };
    replay::write_estimates(out, &report.estimates)?;
    eprintln!(
        "{}: {} estimates from {} measurements with {estimator} in {:.1} ms -> {}",
        data.scenario.name,
        report.estimates.len(),
        report.measurements,
        report.elapsed.as_secs_f64() * 1e3,
        out.display()
    );
    if report.skipped_nonfinite > 0 {
        eprintln!(
            "skipped {} measurements with non-finite values",
            report.skipped_nonfinite
        );
    }
    if !report.rejected.is_empty() {
        eprintln!(
            "rejected the measurements of {} times (state kept):",
            report.rejected.len()
        );
        for (t, why) in report.rejected.iter().take(5) {
            eprintln!("  t = {t}: {why}");
        }
    }
    if let Some(a) = report.association {
        eprintln!(
            "association: {} clusters solved (largest {} tracks), largest net {}, {} capped by \
             their bound",
            a.clusters, a.largest_cluster, a.largest_net, a.capped
        );
    }
    if estimator == "tracker" {
        return print_multi_score(dir, &report, json);
    }
    if let Some(score) = &report.score {
        if json {
            out!(
                "{}",
                serde_json::to_string_pretty(score).unwrap_or_default()
            );
        } else {
            for line in replay::summary_lines(score) {
                out!("{line}");
            }
        }
    }
    Ok(())
}

/// The multi-target score of a tracker's estimates (`harrier track-eval`'s: GOSPA c = 20 m, p = 2,
/// continuity), when the scenario has a multi-target truth.
fn print_multi_score(
    dir: &std::path::Path,
    report: &replay::ReplayReport,
    json: bool,
) -> Result<(), replay::ReplayError> {
    use harrier_tools::track_eval;
    let score = track_eval::score_dir(dir, &report.estimates, 20.0)
        .map_err(|e| replay::ReplayError::Setup(format!("{e:#}")))?;
    match score {
        Some(s) if json => out!("{}", serde_json::to_string_pretty(&s).unwrap_or_default()),
        Some(s) => out!("{}", track_eval::summary(&s, 20.0)),
        None => {}
    }
    Ok(())
}
