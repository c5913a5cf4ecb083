//! The interactive 3D pages of the CLI (`tdpcr::view`), written atomically: `--view
//! FILE.html` of `fk`, `ik` and `analyze` (the solved configuration) and the
//! `workspace.html` of `workspace --out DIR`, and the SVG sketch `configuration.svg` of
//! `analyze --plot DIR`.

use std::path::{Path, PathBuf};

use tdpcr::Tdpcr;
use tdpcr::analysis::Ellipsoids;
use tdpcr::error::Error;
use tdpcr::kinetostatics::{Solution, Solver};
use tdpcr::model::Model;
use tdpcr::view::robot::EllipsoidView;
use tdpcr::view::{RobotView, robot_figure, workspace_figure, write_page};
use tdpcr::workspace::WorkspaceMap;

/// Writes the page of `sol` to `path`, with the J_p and C_p ellipsoids if given.
pub fn write_configuration(
    path: &Path,
    command: &str,
    solver: &Solver,
    sol: &Solution,
    ellipsoids: Option<&Ellipsoids>,
) -> Result<(), Error> {
    let shown: Vec<EllipsoidView> = ellipsoids
        .map(|e| {
            vec![
                EllipsoidView {
                    name: "J_p".into(),
                    unit: "m/m".into(),
                    ellipsoid: e.j_p,
                    color: "#2ca02c".into(),
                },
                EllipsoidView {
                    name: "C_p".into(),
                    unit: "m/N".into(),
                    ellipsoid: e.c_p,
                    color: "#ff7f0e".into(),
                },
            ]
        })
        .unwrap_or_default();
    let p = sol.state.position;
    let title = format!(
        "tdpcr {command}: platform at ({:.2}, {:.2}, {:.2}) mm",
        p[0] * 1e3,
        p[1] * 1e3,
        p[2] * 1e3
    );
    let view = RobotView {
        model: solver.model(),
        state: &sol.state,
        ellipsoids: &shown,
    };
    let figure = robot_figure(&title, &view)?;
    write_page(path, &figure)?;
    Ok(())
}

/// Writes `workspace.html` into `dir` (which exists: the map's files are written first)
/// with the home configuration (the cell at the origin, if reachable) and returns its path.
pub fn write_workspace(dir: &Path, design: &Tdpcr, map: &WorkspaceMap) -> Result<PathBuf, Error> {
    let model = Model::new(design);
    let home = map
        .points
        .iter()
        .find(|p| p.cell == [0, 0, 0] && p.reachable())
        .map(|p| &p.state);
    let figure = workspace_figure(map, &model, home)?;
    let path = dir.join("workspace.html");
    write_page(&path, &figure)?;
    Ok(path)
}

/// Writes `configuration.svg` (three orthographic views of `sol`) into `dir`, which
/// exists (the ellipsoid plots are written first), and returns its path.
pub fn write_sketch(dir: &Path, solver: &Solver, sol: &Solution) -> Result<PathBuf, Error> {
    std::fs::create_dir_all(dir).map_err(|source| tdpcr::error::PlotError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let svg = tdpcr::view::sketch::configuration_svg(solver.model(), &sol.state)?;
    let path = dir.join("configuration.svg");
    tdpcr::output::write_atomically(&path, svg.as_bytes())?;
    Ok(path)
}
