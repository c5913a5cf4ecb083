//! `tdpcr validate`: load and validate a design file (TDCR or TDPCR), print a summary.

use tdpcr::error::Error;
use tdpcr::{Tdcr, Tdpcr};

use crate::args::ValidateArgs;

/// Runs `tdpcr validate`.
pub fn run(args: &ValidateArgs) -> Result<(), Error> {
    let text = std::fs::read_to_string(&args.design).map_err(|source| tdpcr::DesignError::Io {
        path: args.design.clone(),
        source,
    })?;
    let source = args.design.display().to_string();
    if text
        .trim_start_matches(|c: char| c.is_whitespace())
        .lines()
        .any(|l| l.trim_start().starts_with("Tdpcr("))
    {
        let d = Tdpcr::from_ron_str(&text, &source)?;
        println!(
            "{source}: valid TDPCR, {}-DoF ({} tendons per leg), leg length {} m",
            d.n_actuators(),
            d.leg.tendons.len(),
            d.leg.length
        );
    } else {
        let r = Tdcr::from_ron_str(&text, &source)?;
        println!(
            "{source}: valid TDCR, {} tendons, length {} m, {} integration steps ({:?})",
            r.leg.tendons.len(),
            r.leg.length,
            r.leg.integration_steps,
            r.leg.integrator
        );
    }
    Ok(())
}
