//! `tdpcr jacobian-check`: the exact Jacobian blocks against finite differences, with the
//! time of each.

use tdpcr::Tdpcr;
use tdpcr::error::Error;
use tdpcr::kinetostatics::Solver;

use crate::args::JacobianCheckArgs;
use crate::output;

/// Runs `tdpcr jacobian-check`.
pub fn run(args: &JacobianCheckArgs) -> Result<(), Error> {
    let design = Tdpcr::from_ron_file(&args.design)?;
    let mut solver = Solver::new(&design)?;
    let check = tdpcr::jacobian_check::jacobian_check(&mut solver, args.samples, args.seed);
    output::print(args.format, &check, |check| {
        let e = &check.max_rel_error;
        println!("configurations solved: {}/{}", check.solved, check.samples);
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
    if check.solved == 0 {
        let mut v = tdpcr::error::Violations::default();
        v.push(
            "--samples",
            args.samples,
            "at least one configuration that solves",
        );
        return Err(Error::Input(v));
    }
    Ok(())
}
