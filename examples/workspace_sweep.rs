//! One workspace sweep of a design, printing the summary as JSON:
//! `cargo run --release --example workspace_sweep -- [DESIGN.ron] [STEP] [ANGLE_STEP] [ZMIN]
//! [ZMAX] [TOLERANCE] [MAX_ITERATIONS]` (defaults: those of `WorkspaceSettings`).

use tdpcr::Tdpcr;
use tdpcr::workspace::{WorkspaceSettings, sweep_workspace};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .cloned()
        .unwrap_or_else(|| format!("{}/designs/lilge2022.ron", env!("CARGO_MANIFEST_DIR")));
    let num = |i: usize, default: f64| -> f64 {
        args.get(i).and_then(|s| s.parse().ok()).unwrap_or(default)
    };
    let design = Tdpcr::from_ron_file(&path)?;
    let defaults = WorkspaceSettings::default();
    let settings = WorkspaceSettings {
        step: num(1, defaults.step),
        angle_step: num(2, defaults.angle_step),
        z_range: [num(3, defaults.z_range[0]), num(4, defaults.z_range[1])],
        tolerance: num(5, defaults.tolerance),
        max_iterations: num(6, defaults.max_iterations as f64) as usize,
        ..defaults
    };
    let map = sweep_workspace(&design, &settings)?;
    println!("{}", serde_json::to_string_pretty(&map.summary)?);
    Ok(())
}
