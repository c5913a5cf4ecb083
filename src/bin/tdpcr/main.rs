//! The `tdpcr` command-line tool: a thin layer over the library (argument parsing,
//! output formatting, exit codes). Exit codes: 0 success, 1 a solve failed, 2 bad input.
//!
//! Layout: [`args`] (the clap structs and value parsers), one module per subcommand
//! ([`solve`] for `fk` and `ik`, [`analyze`], [`tdcr`], [`trajectory`], [`jacobian_check`],
//! [`workspace`], [`validate`]), [`output`] (JSON or text on stdout) and [`view`] (the
//! `--view` HTML page).

mod analyze;
mod args;
mod jacobian_check;
mod output;
mod solve;
mod tdcr;
mod trajectory;
mod validate;
mod view;
mod workspace;

use std::process::ExitCode;

use clap::Parser;

use args::{Cli, Command};
use tdpcr::error::Error;

fn main() -> ExitCode {
    tdpcr::cli_support::end_quietly_on_broken_pipe();
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Tdcr(a) => tdcr::run(a),
        Command::Fk(a) => solve::run_fk(a),
        Command::Ik(a) => solve::run_ik(a),
        Command::Analyze(a) => analyze::run(a),
        Command::Trajectory(a) => trajectory::run(a),
        Command::JacobianCheck(a) => jacobian_check::run(a),
        Command::Workspace(a) => workspace::run(a),
        Command::Validate(a) => validate::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            match e {
                Error::Solve(_) | Error::Analysis(_) => ExitCode::from(1),
                _ => ExitCode::from(2),
            }
        }
    }
}
