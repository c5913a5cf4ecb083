//! The workspace map on disk: `points.csv`, `summary.json` and the slice figures (feature
//! `plots`), each written atomically (a temporary file in the same directory, then a
//! rename), so an interrupted run leaves either the complete file or none.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::decimal::{push_display, push_lower_exp};
use crate::error::Error;
use crate::output::{WriteError, check_target, write_atomically, write_atomically_with};
use crate::workspace::{WorkspaceMap, WorkspacePoint};

/// The CSV header: `x,y,z`, `q1..qn`, `tau_<leg>_<tendon>` (1-based), `min_tension`, every
/// raw rcond (`rcond_b_xu, rcond_b_qu, rcond_b_u, rcond_j_p, rcond_j_o, rcond_c_p,
/// rcond_c_o`), the same unit-scaled (`rcond_scaled_...`), then the flags
/// `near_type_i, near_type_ii, near_leg_singularity, collision, unstable` (0 or 1;
/// `unstable`: the equilibrium is unstable with the actuators held and ended its ray),
/// then `min_compliance_eigenvalue` (smallest eigenvalue of the unit-scaled sym(C)).
pub fn csv_header(n_actuators: usize, tendons_per_leg: usize) -> Vec<String> {
    let mut h: Vec<String> = ["x", "y", "z"].map(String::from).to_vec();
    h.extend((1..=n_actuators).map(|i| format!("q{i}")));
    for leg in 1..=3 {
        h.extend((1..=tendons_per_leg).map(|k| format!("tau_{leg}_{k}")));
    }
    h.push("min_tension".into());
    const RCONDS: [&str; 7] = ["b_xu", "b_qu", "b_u", "j_p", "j_o", "c_p", "c_o"];
    h.extend(RCONDS.iter().map(|r| format!("rcond_{r}")));
    h.extend(RCONDS.iter().map(|r| format!("rcond_scaled_{r}")));
    h.extend(
        [
            "near_type_i",
            "near_type_ii",
            "near_leg_singularity",
            "collision",
            "unstable",
            "min_compliance_eigenvalue",
        ]
        .map(String::from),
    );
    h
}

/// `points.csv` as text: the header of [`csv_header`], then one line per cell (reachable
/// and collision), in the map's order. Numbers are written with the shortest digits that
/// read back to the same f64 (exponent form below 1e-4), as std's `{}` and `{:e}` print
/// them (module `decimal`, from zmij's digits: 2.3× fewer instructions than std's
/// formatting). The lines are formatted in parallel blocks (rayon, on the current pool)
/// and joined in order: the same text as one line after the other. For 69 750 cells of
/// the reference design (39 MB) on the 2-core AMD machine with std's formatting:
/// 0.20–0.24 s on two threads, 0.27–0.45 s on one.
pub fn points_csv(map: &WorkspaceMap) -> String {
    let mut out = csv_header_line(map);
    let blocks = csv_blocks(&map.points);
    out.reserve(blocks.iter().map(String::len).sum());
    for block in blocks {
        out.push_str(&block);
    }
    out
}

/// Writes [`points_csv`]'s text to `path` atomically, each group of blocks written while
/// the next is formatted: the reference design's 100 MB took 0.46–0.48 s to format and
/// then 0.31–0.35 s to write and sync (2 cores, AMD EPYC, 2026-11-27).
fn write_points_csv(map: &WorkspaceMap, path: &Path) -> Result<(), WriteError> {
    write_atomically_with(path, |file| {
        file.write_all(csv_header_line(map).as_bytes())?;
        let write = |file: &mut fs::File, blocks: &[String]| {
            blocks.iter().try_for_each(|b| file.write_all(b.as_bytes()))
        };
        let mut pending = Vec::new();
        for group in map.points.chunks(CSV_BLOCK * CSV_GROUP) {
            let (next, written) = rayon::join(|| csv_blocks(group), || write(file, &pending));
            written?;
            pending = next;
        }
        write(file, &pending)
    })
}

/// The header line of `points.csv` (with its newline).
fn csv_header_line(map: &WorkspaceMap) -> String {
    let mut line = csv_header(map.n_actuators, map.tendons_per_leg).join(",");
    line.push('\n');
    line
}

/// The lines of `points`, formatted in parallel blocks of [`CSV_BLOCK`] cells.
fn csv_blocks(points: &[WorkspacePoint]) -> Vec<String> {
    points
        .par_chunks(CSV_BLOCK)
        .map(|points| {
            let mut block = String::with_capacity(600 * points.len());
            let mut digits = zmij::Buffer::new();
            for p in points {
                write_csv_line(&mut block, p, &mut digits);
            }
            block
        })
        .collect()
}

/// Cells per block of [`points_csv`]'s parallel formatting.
const CSV_BLOCK: usize = 4096;

/// Blocks per group of [`write_points_csv`] (about 10 MB of text).
const CSV_GROUP: usize = 4;

/// One line of `points.csv` for `p` (with its newline).
fn write_csv_line(out: &mut String, p: &WorkspacePoint, digits: &mut zmij::Buffer) {
    let (r, s, m) = (&p.metrics.rcond, &p.metrics.rcond_scaled, &p.metrics);
    let numbers = p
        .position
        .iter()
        .chain(&p.state.q)
        .chain(&p.tensions)
        .chain([&m.min_tension])
        .chain([&r.b_xu, &r.b_qu, &r.b_u, &r.j_p, &r.j_o, &r.c_p, &r.c_o])
        .chain([&s.b_xu, &s.b_qu, &s.b_u, &s.j_p, &s.j_o, &s.c_p, &s.c_o]);
    for x in numbers {
        // Every value is finite by construction; guard anyway (no NaN in outputs).
        let x = if x.is_finite() { *x } else { 0.0 };
        // Shortest round-trip digits; exponent form for tiny values (rcond ~ 1e-9).
        if x == 0.0 || (1e-4..1e15).contains(&x.abs()) {
            push_display(out, x, digits);
        } else {
            push_lower_exp(out, x, digits);
        }
        out.push(',');
    }
    let f = &m.singularity;
    for set in [f.type_i, f.type_ii, f.leg, p.collision, !m.stable] {
        out.push_str(if set { "1," } else { "0," });
    }
    let e = m.min_compliance_eigenvalue;
    let e = if e.is_finite() { e } else { 0.0 };
    push_lower_exp(out, e, digits);
    out.push('\n');
}

/// Creates the output directory `dir` (and its parents) if missing.
///
/// # Errors
/// [`Error::Output`] naming `dir`.
pub fn create_output_dir(dir: &Path) -> Result<(), Error> {
    create_output_dir_levels(dir).map(drop)
}

/// [`create_output_dir`], returning the directories it created (outermost first).
fn create_output_dir_levels(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let error = |source| Error::Output {
        path: dir.to_path_buf(),
        source,
    };
    if fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
        return Err(error(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "it exists and is not a directory: expected a directory or a new directory's path",
        )));
    }
    create_missing_levels(dir).map_err(error)
}

/// Creates `dir` and its missing parents one level at a time, outermost first, and
/// returns the directories this call created (outermost first): exactly those, so that
/// they can be removed again ([`remove_created_dirs`]). Whether a level exists is decided
/// by creating it, not by looking up the path first (`new/../kept` does not resolve
/// before `new` exists: judged missing, `kept` was removed after a failed sweep).
fn create_missing_levels(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut levels: Vec<&Path> = dir
        .ancestors()
        .filter(|p| !p.as_os_str().is_empty())
        .collect();
    levels.reverse();
    let mut created = Vec::new();
    for level in levels {
        match fs::create_dir(level) {
            Ok(()) => created.push(level.to_path_buf()),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
    }
    Ok(created)
}

/// Removes the directories of `created` (as [`prepare_output_dir_created`] returns them)
/// that are still empty, deepest first; anything else stays.
pub fn remove_created_dirs(created: &[PathBuf]) {
    for dir in created.iter().rev() {
        let _ = fs::remove_dir(dir);
    }
}

/// Makes `dir` ready for a sweep's files before the sweep: creates it (and its parents)
/// if missing, checks that a file can be created in it, and that none of `names` exists
/// there as anything but a regular file, so that a sweep never runs for minutes to fail
/// at its first write or leave a mixed set of files.
///
/// # Errors
/// [`Error::Output`] naming the directory or the file.
pub fn prepare_output_dir(dir: &Path, names: &[&str]) -> Result<(), Error> {
    prepare_output_dir_created(dir, names).map(drop)
}

/// [`prepare_output_dir`], returning the directories it created (outermost first) for
/// [`remove_created_dirs`] after a run that failed before writing anything.
///
/// # Errors
/// As [`prepare_output_dir`].
pub fn prepare_output_dir_created(dir: &Path, names: &[&str]) -> Result<Vec<PathBuf>, Error> {
    let created = create_output_dir_levels(dir)?;
    let checked = check_output_dir(dir, names);
    if checked.is_err() {
        remove_created_dirs(&created);
    }
    checked.map(|()| created)
}

/// The checks of [`prepare_output_dir`] on an existing `dir`.
fn check_output_dir(dir: &Path, names: &[&str]) -> Result<(), Error> {
    let probe = dir.join(format!(".tdpcr-probe.{}", std::process::id()));
    fs::File::create(&probe)
        .and_then(|_| fs::remove_file(&probe))
        .map_err(|source| Error::Output {
            path: dir.to_path_buf(),
            source,
        })?;
    for name in names {
        check_target(&dir.join(name))?;
    }
    Ok(())
}

/// Writes `points.csv`, `summary.json` and (with the `plots` feature) the slice figures of
/// `workspace::figures` into `dir` (created if missing). Returns the paths written, in
/// that order.
///
/// # Errors
/// [`Error::Output`] naming the file that could not be written.
pub fn write_outputs(map: &WorkspaceMap, dir: &Path) -> Result<Vec<PathBuf>, Error> {
    create_output_dir(dir)?;
    let mut written = Vec::new();
    let points = dir.join("points.csv");
    write_points_csv(map, &points)?;
    written.push(points);
    let summary = dir.join("summary.json");
    let json = serde_json::to_string_pretty(&map.summary).expect("plain data serializes");
    write_atomically(&summary, (json + "\n").as_bytes())?;
    written.push(summary);
    #[cfg(feature = "plots")]
    {
        let figures = crate::workspace::figures::slice_figures(map);
        let names: Vec<&str> = figures.iter().map(|(name, _)| name.as_str()).collect();
        remove_other_slice_figures(dir, &names)?;
        for (name, svg) in &figures {
            let path = dir.join(name);
            write_atomically(&path, svg.as_bytes())?;
            written.push(path);
        }
    }
    Ok(written)
}

/// Removes the slice figures of an earlier sweep in `dir` that are not among `keep` (a
/// sweep at another Δ draws other planes: `reach_z+0.060.svg` stayed beside this sweep's
/// `reach_z+0.066.svg`). Only names of the figures' own pattern
/// (`{reach,rcond,tension}_z±D.DDD.svg`) are touched.
///
/// # Errors
/// [`Error::Output`] naming a figure that could not be removed.
#[cfg(feature = "plots")]
fn remove_other_slice_figures(dir: &Path, keep: &[&str]) -> Result<(), Error> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        if is_slice_figure_name(name) && !keep.contains(&name) && entry.path().is_file() {
            fs::remove_file(entry.path()).map_err(|source| Error::Output {
                path: entry.path(),
                source,
            })?;
        }
    }
    Ok(())
}

/// Whether `name` is a slice figure's: `{reach,rcond,tension}_z`, a sign, digits, a
/// point, three digits, `.svg`.
#[cfg(feature = "plots")]
fn is_slice_figure_name(name: &str) -> bool {
    let Some(rest) = ["reach_z", "rcond_z", "tension_z"]
        .iter()
        .find_map(|p| name.strip_prefix(p))
        .and_then(|r| r.strip_suffix(".svg"))
    else {
        return false;
    };
    let Some(number) = rest.strip_prefix('+').or_else(|| rest.strip_prefix('-')) else {
        return false;
    };
    match number.split_once('.') {
        Some((whole, frac)) => {
            !whole.is_empty()
                && frac.len() == 3
                && whole
                    .bytes()
                    .chain(frac.bytes())
                    .all(|b| b.is_ascii_digit())
        }
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_names_the_file() {
        let bad = std::env::temp_dir()
            .join(format!("tdpcr-missing-{}", std::process::id()))
            .join("b.txt");
        let msg = write_atomically(&bad, b"x").unwrap_err().to_string();
        assert!(
            msg.starts_with("cannot write") && msg.contains("b.txt"),
            "{msg}"
        );
    }

    #[cfg(feature = "plots")]
    #[test]
    fn only_the_slice_figures_own_names_are_taken_for_figures() {
        for name in [
            "reach_z+0.060.svg",
            "rcond_z-0.066.svg",
            "tension_z+12.000.svg",
        ] {
            assert!(is_slice_figure_name(name), "{name}");
        }
        for name in [
            "reach_z0.060.svg",
            "reach_z+0.06.svg",
            "my_reach_z+0.060.svg",
            "reach_z+0.060.svg.bak",
            "reach_z+.060.svg",
            "points.csv",
            "reach_z+0.06a.svg",
        ] {
            assert!(!is_slice_figure_name(name), "{name}");
        }
    }

    #[test]
    fn header_names_every_column_in_order() {
        let h = csv_header(6, 2).join(",");
        assert!(
            h.starts_with("x,y,z,q1,q2,q3,q4,q5,q6,tau_1_1,tau_1_2,tau_2_1,"),
            "{h}"
        );
        assert!(h.contains(",tau_3_2,min_tension,rcond_b_xu,rcond_b_qu,rcond_b_u,rcond_j_p,"));
        assert!(h.contains(",rcond_c_o,rcond_scaled_b_xu,"));
        assert!(h.ends_with(
            "rcond_scaled_c_o,near_type_i,near_type_ii,near_leg_singularity,collision,\
                 unstable,min_compliance_eigenvalue"
        ));
        assert_eq!(csv_header(9, 4).len(), 3 + 9 + 12 + 1 + 14 + 6);
    }
}
