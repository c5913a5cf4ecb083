//! `tdpcr trajectory`: a CSV of IK poses or FK actuations solved in order, each step
//! warm-started from the last (the first from `--init` if given, else cold;
//! [`tdpcr::trajectory::run_trajectory_from`]), the IK steps with
//! the redundancy resolution of `ik` (`--limits`, `--reference`, mapped by the one
//! [`crate::args::RedundancyArgs::apply`]); the CSV reader and the per-step rows printed
//! as CSV.

use std::path::Path;

use nalgebra::{Rotation3, Vector3};
use serde::Serialize;

use tdpcr::SolveError;
use tdpcr::error::{Error, Violations};
use tdpcr::kinetostatics::Redundancy;
use tdpcr::model::Pose;
use tdpcr::trajectory::{Stats, StepResult, Targets, run_trajectory_from};

use crate::args::TrajectoryArgs;
use crate::output;
use crate::solve::prepare;

#[derive(Serialize)]
struct TrajectoryOutput {
    steps: Vec<StepResult>,
    stats: Stats,
}

/// Runs `tdpcr trajectory`.
pub fn run(args: &TrajectoryArgs) -> Result<(), Error> {
    let (mut solver, wrench, init) = prepare(&args.design, &args.solve)?;
    if args.fk.is_some() && args.redundancy.given() {
        let mut v = Violations::default();
        v.push(
            "--limits/--reference",
            "given with --fk",
            "only with --ik (FK has no redundancy to resolve)",
        );
        return Err(Error::Input(v));
    }
    args.redundancy.apply(&mut solver)?;
    if args.reuse_factorization {
        let least_norm_ik = args.ik.is_some() && solver.redundancy == Redundancy::LeastNorm;
        if !least_norm_ik || solver.model().pairs == 1 {
            let mut v = Violations::default();
            v.push(
                "--reuse-factorization",
                "given",
                "only with --ik and --limits free on a design with two tendon pairs per leg (least-norm IK steps)",
            );
            return Err(Error::Input(v));
        }
        solver.reuse_least_norm_factorization = true;
    }
    if let Some(state) = &init {
        solver.check_warm_start(state)?;
    }
    let targets = match (&args.ik, &args.fk) {
        (Some(path), _) => {
            let rows = read_csv(path, 6, "x,y,z,rx,ry,rz", true)?;
            Targets::Poses(poses_from_rows(&rows))
        }
        (None, Some(path)) => {
            let n = solver.model().n_actuators();
            let what = format!("q1..q{n}");
            Targets::Actuations(read_csv(path, n, &what, false)?)
        }
        (None, None) => unreachable!("clap requires --ik or --fk"),
    };
    let (steps, stats) = run_trajectory_from(&mut solver, &targets, &wrench, init);
    let out = TrajectoryOutput { steps, stats };
    output::print(args.solve.format, &out, print_rows);
    if let Some(first_step) = out.stats.first_failed_step {
        return Err(Error::Solve(SolveError::TrajectoryStepsFailed {
            failed: out.stats.failed,
            steps: out.stats.steps,
            first_step,
            first_failure: out.stats.first_failure.clone().unwrap_or_default(),
        }));
    }
    Ok(())
}

/// The text form of `trajectory`: one CSV row per step on stdout, the statistics on
/// stderr.
fn print_rows(TrajectoryOutput { steps, stats }: &TrajectoryOutput) {
    println!("step,converged,iterations,solve_time_us,x,y,z,rx,ry,rz,q");
    // A failed FK step has no pose: its six fields are empty.
    let fields = |v: Option<[f64; 3]>| {
        v.map_or_else(
            || ",,".to_string(),
            |v| format!("{},{},{}", v[0], v[1], v[2]),
        )
    };
    for s in steps {
        let q: Vec<String> = s.q.iter().map(|x| x.to_string()).collect();
        println!(
            "{},{},{},{:.1},{},{},{}",
            s.step,
            s.converged,
            s.iterations,
            s.solve_time_us,
            fields(s.position),
            fields(s.rotvec),
            q.join(";")
        );
    }
    if let (Some(k), Some(why)) = (stats.first_failed_step, &stats.first_failure) {
        eprintln!("first failed step: {k}: {why}");
    }
    eprintln!(
        "{} steps, {} failed; per step: median {:.0} µs, mean {:.0} µs, max {:.0} µs, median {} iterations",
        stats.steps,
        stats.failed,
        stats.median_us,
        stats.mean_us,
        stats.max_us,
        stats.median_iterations
    );
}

/// The most bytes a trajectory CSV may have (about 4 million rows of poses).
const MAX_CSV_BYTES: u64 = 256 << 20;

/// Reads a CSV of numbers with `width` columns (blank lines and lines starting with `#`
/// are ignored; the first other line is a header, and skipped, if none of its fields is
/// a number: a row of `NaN` or `inf` is data, and an error; a UTF-8 byte-order mark is
/// dropped). With `poses`, columns 4–6 are a rotation vector
/// ([`tdpcr::spatial::is_rotation_vector`]).
///
/// # Errors
/// [`Error::Input`] naming the file, line and column of every bad field.
fn read_csv(path: &Path, width: usize, what: &str, poses: bool) -> Result<Vec<Vec<f64>>, Error> {
    let text =
        tdpcr::design::read_text_at_most(path, MAX_CSV_BYTES, "a trajectory CSV").map_err(|e| {
            let mut v = Violations::default();
            v.push(
                path.display().to_string(),
                "unreadable",
                &format!("a readable CSV file ({e})"),
            );
            Error::Input(v)
        })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut rows = Vec::new();
    let mut v = Violations::default();
    let mut first = true;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let header = first && fields.iter().all(|f| f.parse::<f64>().is_err());
        first = false;
        if header {
            continue;
        }
        let parsed: Vec<Option<f64>> = fields
            .iter()
            .map(|f| f.parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect();
        let at = |c: usize| format!("{}:{}:{}", path.display(), i + 1, c + 1);
        if fields.len() != width {
            v.push(
                at(0),
                tdpcr::error::counted(fields.len(), "column"),
                &format!("{width} columns: {what}"),
            );
            continue;
        }
        for (c, p) in parsed.iter().enumerate() {
            if p.is_none() {
                v.push(at(c), fields[c], "a finite number");
            }
        }
        // A pose row's rotation vector (columns 4-6).
        if poses
            && let [Some(a), Some(b), Some(c)] = parsed[3..6]
            && !tdpcr::spatial::is_rotation_vector(&Vector3::new(a, b, c))
        {
            v.push(at(3), fields[3..6].join(","), tdpcr::spatial::ROTVEC_RULE);
        }
        rows.push(parsed.into_iter().map(|p| p.unwrap_or(0.0)).collect());
    }
    if rows.is_empty() && v.0.is_empty() {
        v.push(
            path.display().to_string(),
            "no data rows",
            &format!("at least one row of {what}"),
        );
    }
    if v.0.is_empty() {
        Ok(rows)
    } else {
        Err(Error::Input(v))
    }
}

/// Poses from rows x,y,z,rx,ry,rz.
fn poses_from_rows(rows: &[Vec<f64>]) -> Vec<Pose> {
    rows.iter()
        .map(|r| Pose {
            position: Vector3::new(r[0], r[1], r[2]),
            rotation: *Rotation3::new(Vector3::new(r[3], r[4], r[5])).matrix(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_reader_skips_a_header_and_names_bad_fields() {
        let dir = std::env::temp_dir().join(format!("tdpcr-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("poses.csv");
        std::fs::write(
            &path,
            "x,y,z,rx,ry,rz\n0,0,0,0,0,0\n# comment\n\n0.001,0,0,0,0,0\n",
        )
        .unwrap();
        let rows = read_csv(&path, 6, "x,y,z,rx,ry,rz", true).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[1][0], 0.001);
        std::fs::write(&path, "0,0,0,0,0,0\n0,abc,0,0,0,0\n0,0,0\n").unwrap();
        let msg = read_csv(&path, 6, "x,y,z,rx,ry,rz", true)
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("poses.csv:2:2 = abc: expected a finite number"),
            "{msg}"
        );
        assert!(
            msg.contains("poses.csv:3:1 = 3 columns: expected 6 columns"),
            "{msg}"
        );
        // The error of `text` as the file.
        let error_of = |text: &str| {
            std::fs::write(&path, text).unwrap();
            read_csv(&path, 6, "x,y,z,rx,ry,rz", true)
                .unwrap_err()
                .to_string()
        };
        // Only the first line can be a header: a row of NaN is data, and a second
        // non-numeric line is an error, not another header.
        let msg = error_of("NaN,NaN,NaN,NaN,NaN,NaN\n0,0,0,0,0,0\n");
        assert!(
            msg.contains("poses.csv:1:1 = NaN: expected a finite number"),
            "{msg}"
        );
        let msg = error_of("a,b,c,d,e,f\ng,h,i,j,k,l\n0,0,0,0,0,0\n");
        assert!(
            msg.contains("poses.csv:2:1 = g: expected a finite number"),
            "{msg}"
        );
        // Another separator: the second line has one column.
        let msg = error_of("x;y;z;rx;ry;rz\n0;0;0;0;0;0\n");
        assert!(
            msg.contains("poses.csv:2:1 = 1 column: expected 6 columns"),
            "{msg}"
        );
        // A byte-order mark before the first row.
        std::fs::write(&path, "\u{feff}0,0,0,0,0,0\n").unwrap();
        assert_eq!(read_csv(&path, 6, "x,y,z,rx,ry,rz", true).unwrap().len(), 1);
        std::fs::remove_dir_all(&dir).ok();
    }
}
