//! Shared by the binary's end-to-end tests: running it and a tiny search config.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `tdpcr-optim` with `args` to completion.
pub fn optim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tdpcr-optim"))
        .args(args)
        .output()
        .expect("binary runs")
}

/// An empty directory `name` under `group` in the test target's temporary directory.
pub fn fresh_dir(group: &str, name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A search of 3 parameters at Δ = 30 mm, φ = 1.2 rad (a fraction of a second per
/// evaluation), population 4.
pub fn tiny_config(dir: &Path) -> PathBuf {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../designs/lilge2022.ron");
    let text = format!(
        r#"OptimConfig(
    base_design: "{}",
    parameters: [
        Bounds(parameter: Alpha, min: 0.4, max: 0.7),
        Bounds(parameter: LegLength, min: 0.13, max: 0.16),
        Bounds(parameter: Pretension, min: 0.0, max: 1.0),
    ],
    evaluation: Evaluation(step: 0.03, angle_step: 1.2, z_range: (-0.06, 0.06),
                           orientations: [(0.0, 0.0, 0.0)], max_iterations: 20, tolerance: 1e-8),
    objectives: [Weighted(objective: WorkspaceVolume, weight: 1.0),
                 Weighted(objective: MeanRcondJp, weight: 1.0)],
    budget: Budget(evaluations: Some(100)),
    seed: 4,
    population: Some(4),
    figures: Some(FigureSweep(step: 0.03, angle_step: 1.2)),
)"#,
        base.display()
    );
    let path = dir.join("tiny.ron");
    std::fs::write(&path, text).unwrap();
    path
}
