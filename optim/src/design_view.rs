//! `designs.html` of a search: the reference and the best-composite design side by side
//! as interactive 3D views (`tdpcr::view`), each in its home configuration (the platform
//! at the origin with R_ee = I, solved from a cold start).

use tdpcr::kinetostatics::{RobotState, Solver};
use tdpcr::rod::Wrench;
use tdpcr::view::{RobotView, html_page, robots_figure};
use tdpcr::{Pose, Tdpcr};

use crate::search::{SearchResult, Setup};

/// The home configuration of `design`, or why there is none.
fn home(design: &Tdpcr) -> Result<(Solver, RobotState), String> {
    let mut solver = Solver::new(design).map_err(|e| e.to_string())?;
    let sol = solver
        .solve_ik(&Pose::identity(), &Wrench::default(), None)
        .map_err(|e| e.to_string())?;
    Ok((solver, sol.state))
}

/// The page, or `None` if no design (the reference nor the best) has a home configuration.
/// A design whose home configuration cannot be solved is left out; the title says so.
pub fn designs_page(setup: &Setup, result: &SearchResult) -> Option<String> {
    let mut designs = vec![("reference".to_owned(), setup.space.base().clone())];
    if let Some(best) = result.best_composite()
        && let Ok(design) = setup.space.design(&best.x)
    {
        designs.push((format!("best composite (candidate {})", best.id), design));
    }
    let mut solved = Vec::new();
    let mut missing = Vec::new();
    for (label, design) in &designs {
        match home(design) {
            Ok((solver, state)) => solved.push((label.clone(), solver, state)),
            Err(e) => missing.push(format!("{label}: no home configuration ({e})")),
        }
    }
    if solved.is_empty() {
        return None;
    }
    let views: Vec<(&str, RobotView)> = solved
        .iter()
        .map(|(label, solver, state)| {
            let view = RobotView {
                model: solver.model(),
                state,
                ellipsoids: &[],
            };
            (label.as_str(), view)
        })
        .collect();
    let mut title =
        "tdpcr-optim: home configurations (platform at the origin, R_ee = I)".to_owned();
    for m in &missing {
        title.push_str("; ");
        title.push_str(m);
    }
    robots_figure(&title, &views).ok().map(|f| html_page(&f))
}
