//! `tdpcr jacobian-check`: the exact Jacobian blocks against finite differences, with the
//! time of each.

use tdpcr::Tdpcr;
use tdpcr::error::Error;
use tdpcr::kinetostatics::Solver;

use crate::args::JacobianCheckArgs;
use crate::output;

/// Runs `tdpcr jacobian-check`.
pub fn run(args: &JacobianCheckArgs) -> Result<(), Error> {
    if !(1..=MAX_SAMPLES).contains(&args.samples) {
        let mut v = tdpcr::error::Violations::default();
        v.push(
            "--samples",
            args.samples,
            &format!("1 to {MAX_SAMPLES} configurations"),
        );
        return Err(Error::Input(v));
    }
    let design = Tdpcr::from_ron_file(&args.design)?;
    let mut solver = Solver::new(&design)?;
    let check = tdpcr::jacobian_check::jacobian_check(&mut solver, args.samples, args.seed);
    if check.solved == 0 {
        // Nothing to compare: the samples' failures (in JSON the whole check, `failures`
        // included), and the first as the error (exit 1).
        match args.format {
            crate::args::Format::Json => output::print_json(&check),
            crate::args::Format::Text => {
                for f in &check.failures {
                    eprintln!("sample {}: {}", f.sample, f.error);
                }
            }
        }
        let first = check.first_error.clone();
        return Err(first.map_or_else(
            || {
                let mut v = tdpcr::error::Violations::default();
                v.push("design", "no sample solved", "a design whose FK solves");
                Error::Input(v)
            },
            Error::Solve,
        ));
    }
    output::print(args.format, &check, |check| {
        let e = &check.max_rel_error;
        println!("configurations solved: {}/{}", check.solved, check.samples);
        for f in &check.failures {
            println!("  sample {} not compared: {}", f.sample, f.error);
        }
        println!(
            "max relative error vs central FD: B_x {:.1e}, B_q {:.1e}, B_w {:.1e}, B_u {:.1e}",
            e.b_x, e.b_q, e.b_w, e.b_u
        );
        println!(
            "one Jacobian: exact {:.0} µs, forward FD {:.0} µs ({:.1}x), central FD {:.0} µs ({:.1}x)",
            check.time_exact_us,
            check.time_fd_forward_us,
            check.time_fd_forward_us / check.time_exact_us,
            check.time_fd_central_us,
            check.time_fd_central_us / check.time_exact_us
        );
    });
    Ok(())
}

/// The most configurations `--samples` takes (each costs a cold FK and three Jacobians,
/// about 10 ms on the reference design: 10 000 take minutes).
const MAX_SAMPLES: usize = 10_000;
