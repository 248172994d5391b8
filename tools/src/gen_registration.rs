//! `harrier gen-registration`: a seeded registration scenario (FORMAT-REGISTRATION.md §5)
//! written as a directory.

use anyhow::Context as _;
use harrier_core::registration::generate::{Case, GenConfig, Variant, generate};

/// The configuration from command-line names: `case` one of [`Case::name`]'s, `variant` one of
/// [`Variant::name`]'s, `duration` in seconds.
pub fn config(case: &str, variant: &str, duration: f64) -> anyhow::Result<GenConfig> {
    let names = |v: &[&str]| v.join(", ");
    let case = Case::parse(case).with_context(|| {
        format!(
            "unknown case {case:?}; known: {}",
            names(&Case::ALL.map(Case::name))
        )
    })?;
    let variant = Variant::parse(variant).with_context(|| {
        format!(
            "unknown variant {variant:?}; known: {}",
            names(&Variant::ALL.map(Variant::name))
        )
    })?;
    Ok(GenConfig {
        case,
        variant,
        duration,
    })
}

/// Writes the scenario of `seed` and `cfg` into `dir`, creating it: `scenario.json`,
/// `measurements.jsonl`, `truth.csv`, `bias_truth.csv` and, when the case has references,
/// `references.jsonl` (an old one is removed otherwise).
pub fn write(dir: &std::path::Path, seed: u64, cfg: &GenConfig) -> anyhow::Result<()> {
    let g = generate(seed, cfg)?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, text) in [
        ("scenario.json", &g.scenario_json),
        ("measurements.jsonl", &g.measurements_jsonl),
        ("truth.csv", &g.truth_csv),
        ("bias_truth.csv", &g.bias_truth_csv),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    let refs = dir.join("references.jsonl");
    if g.references_jsonl.is_empty() {
        if refs.exists() {
            std::fs::remove_file(&refs).with_context(|| format!("removing {}", refs.display()))?;
        }
    } else {
        std::fs::write(&refs, &g.references_jsonl)
            .with_context(|| format!("writing {}", refs.display()))?;
    }
    Ok(())
}
