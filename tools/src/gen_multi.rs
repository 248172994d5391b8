//! `harrier gen-multi`: a seeded multi-target scenario written as a directory.

use anyhow::Context as _;
use harrier_core::tracker::generate::groups::{self, GroupConfig, Shape};
use harrier_core::tracker::generate::{GenConfig, Generated, generate};

/// `harrier gen-multi <dir> --seed N`: writes the generator's default crossing-target scenario
/// (`harrier_core::tracker::generate`, FORMAT-MULTI.md §5) into `dir`, creating it.
pub fn write(dir: &std::path::Path, seed: u64) -> anyhow::Result<()> {
    write_generated(dir, &generate(seed, &GenConfig::default())?)
}

/// `harrier gen-multi <dir> --seed N --shape S`: writes a scenario of close groups of turning
/// ground targets of the shape `S` ([`shape_config`]) into `dir`, creating it.
pub fn write_groups(dir: &std::path::Path, seed: u64, shape: &str) -> anyhow::Result<()> {
    write_generated(dir, &groups::generate(seed, &shape_config(shape)?)?)
}

/// The group generator's configuration of a shape name: `crossing`, `parallel`, `opposing`,
/// `mixed` (the generator's defaults: four groups, 10 clutter detections a scan), or `dense`
/// (mixed, 50 clutter detections a scan).
pub fn shape_config(name: &str) -> anyhow::Result<GroupConfig> {
    if name == "dense" {
        return Ok(GroupConfig {
            shape: Shape::Mixed,
            clutter_rate: 50.0,
            ..GroupConfig::default()
        });
    }
    let shape = Shape::parse(name).with_context(|| {
        format!("unknown shape {name:?}: crossing, parallel, opposing, mixed or dense")
    })?;
    Ok(GroupConfig {
        shape,
        ..GroupConfig::default()
    })
}

/// Writes a generated scenario's three files into `dir` (created).
pub fn write_generated(dir: &std::path::Path, g: &Generated) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, text) in [
        ("scenario.json", &g.scenario_json),
        ("measurements.jsonl", &g.measurements_jsonl),
        ("truth.csv", &g.truth_csv),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
