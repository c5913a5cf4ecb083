//! Regenerates `docs/PAPER.md`: every number and figure claim of the paper's Secs. V–VI
//! beside tdpcr's value for the reference design (ψ = 90°) and for its ψ = 0 twin, with
//! whether they agree and why not (MODEL.md §1 says why the reference uses ψ = 90°).
//!
//! ```text
//! cargo run --release --example reproduce_paper              # the paper's resolution, ≈ 6 min on 2 cores
//! cargo run --release --example reproduce_paper -- --quick   # coarse sweeps, ≈ 30 s (CI-sized)
//! cargo run --release --example reproduce_paper -- --out FILE
//! ```
//!
//! The computations are in `claims.rs`, which `tests/paper.rs` runs in quick mode.

mod claims;

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut quick = false;
    let mut out = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/PAPER.md"));
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quick" => quick = true,
            "--out" => match args.next() {
                Some(p) => out = PathBuf::from(p),
                None => {
                    eprintln!("error: --out needs a file path");
                    return ExitCode::from(2);
                }
            },
            other => {
                eprintln!(
                    "error: unknown argument {other:?}; expected --quick or --out FILE \
                     (see the example's doc comment)"
                );
                return ExitCode::from(2);
            }
        }
    }
    let mode = if quick {
        claims::Mode::Quick
    } else {
        claims::Mode::Paper
    };
    let report = match claims::reproduce(mode, &mut |msg| eprintln!("{msg}")) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(1);
        }
    };
    let text = report.markdown();
    if let Err(e) = tdpcr::output::write_atomically(&out, text.as_bytes()) {
        eprintln!("error: cannot write {}: {e}", out.display());
        return ExitCode::from(1);
    }
    let (yes, total) = report.agreement();
    println!("wrote {} ({yes} of {total} claims agree)", out.display());
    ExitCode::SUCCESS
}
