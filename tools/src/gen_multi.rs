//! `harrier gen-multi`: a seeded multi-target scenario written as a directory.

/// `harrier gen-multi <dir> --seed N`: writes the generator's default crossing-target scenario
/// (`harrier_core::tracker::generate`, FORMAT-MULTI.md §5) into `dir`, creating it.
pub fn write(dir: &std::path::Path, seed: u64) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let g = harrier_core::tracker::generate::generate(
        seed,
        &harrier_core::tracker::generate::GenConfig::default(),
    )?;
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
