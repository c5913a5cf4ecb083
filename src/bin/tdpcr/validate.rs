//! `tdpcr validate`: load and validate a design file (TDCR or TDPCR), print a summary.

use tdpcr::error::Error;
use tdpcr::{Tdcr, Tdpcr};

use crate::args::ValidateArgs;

/// Runs `tdpcr validate`.
pub fn run(args: &ValidateArgs) -> Result<(), Error> {
    let text = tdpcr::design::read_design_text(&args.design)?;
    let source = args.design.display().to_string();
    // The file's kind by what parses: a TDPCR file that parses (valid or not) is one, and
    // so is a TDCR file; where neither parses, the error of the kind the text names.
    let parallel = Tdpcr::from_ron_str(&text, &source);
    if !matches!(parallel, Err(tdpcr::DesignError::Parse { .. })) {
        let d = parallel?;
        println!(
            "{source}: valid TDPCR, {}-DoF ({} per leg), leg length {} m",
            d.n_actuators(),
            tdpcr::error::counted(d.leg.tendons.len(), "tendon"),
            d.leg.length
        );
        return Ok(());
    }
    match Tdcr::from_ron_str(&text, &source) {
        Ok(r) => {
            println!(
                "{source}: valid TDCR, {}, length {} m, {} integration steps ({:?})",
                tdpcr::error::counted(r.leg.tendons.len(), "tendon"),
                r.leg.length,
                r.leg.integration_steps,
                r.leg.integrator
            );
            Ok(())
        }
        Err(e @ tdpcr::DesignError::Invalid { .. }) => Err(e.into()),
        Err(single) => {
            let names_parallel = text.contains("Tdpcr") || text.contains("platform");
            Err(match parallel {
                Err(e) if names_parallel => e,
                _ => single,
            }
            .into())
        }
    }
}
