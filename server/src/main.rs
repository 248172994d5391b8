//! `harrier`: the Harrier ground-station command line.
//!
//! ```not_rust
//! harrier estimators
//! harrier replay ../shared/scenarios/radar_bias_none --estimator cdkf --out estimates.jsonl
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use harrier_server::engine::{ESTIMATORS, Params};
use harrier_server::replay;

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
        /// Estimator name (see `harrier estimators`).
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
    },
    /// List the estimators, one line each.
    Estimators {
        /// Also list each estimator's `--param` names.
        #[arg(long)]
        params: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Estimators { params } => {
            for e in ESTIMATORS {
                println!("{:<14} {}", e.name, e.summary);
                for (p, d) in e.params.iter().filter(|_| params) {
                    println!("{:<14}   --param {p}=…  {d}", "");
                }
            }
            ExitCode::SUCCESS
        }
        Command::Replay {
            scenario,
            estimator,
            out,
            params,
            json,
        } => match run_replay(&scenario, &estimator, &out, &params, json) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("harrier replay: error: {e}");
                ExitCode::from(e.exit_code())
            }
        },
    }
}

fn run_replay(
    dir: &std::path::Path,
    estimator: &str,
    out: &std::path::Path,
    params: &[String],
    json: bool,
) -> Result<(), replay::ReplayError> {
    let params = Params::parse(params).map_err(|e| replay::ReplayError::Setup(e.to_string()))?;
    let data = replay::load(dir)?;
    let report = replay::run(&data, estimator, &params)?;
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
    if let Some(score) = &report.score {
        if json {
            println!(
                "{}",
                serde_json::to_string_pretty(score).unwrap_or_default()
            );
        } else {
            for line in replay::summary_lines(score) {
                println!("{line}");
            }
        }
    }
    Ok(())
}
