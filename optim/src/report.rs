//! The output files of a search, in the run directory (all written atomically):
//!
//! - `best_composite.ron`: the feasible candidate with the largest composite;
//! - `pareto_max_volume.ron`, `pareto_max_isotropy.ron`, `pareto_max_margin.ron`: the
//!   Pareto-front members with the largest value of each objective (the front's extremes);
//! - `pareto.csv`: the reference and every Pareto-front member: parameters, the three
//!   objectives, the composite and every other measure;
//! - `report.md`: run summary, a table reference vs best (each objective, each parameter),
//!   and the figures `pareto.svg`, `progress.svg` and, when given, the workspace slices of
//!   the reference and the best design;
//! - `designs.html`: the reference and the best design side by side in 3D
//!   ([`crate::design_view`]).
//!
//! Design files are ordinary `Tdpcr(...)` files: they load with
//! [`tdpcr::Tdpcr::from_ron_file`].

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::OptimError;
use crate::figures::{pareto_figure, progress_figure};
use crate::objectives::{Objective, PARETO_OBJECTIVES};
use crate::runlog::Record;
use crate::search::{SearchResult, Setup};
use crate::space::DesignParameter;
use tdpcr::output::write_atomically;

/// Workspace slice figures of one design (from the workspace module), written to a
/// subdirectory and shown side by side in the report.
#[derive(Debug, Clone, PartialEq)]
pub struct SliceSet {
    /// Column title in the report, e.g. `reference`.
    pub label: String,
    /// Subdirectory of the run directory, e.g. `slices/reference`.
    pub dir: String,
    /// (file name, SVG text).
    pub files: Vec<(String, String)>,
    /// The design's measures from the same (finer) sweep, if computed.
    pub measures: Option<crate::objectives::Measures>,
}

/// What the report says about the circumstances of the run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReportContext {
    /// The command line.
    pub command: String,
    /// Worker threads of the evaluation.
    pub threads: usize,
    /// `/proc/loadavg` at the start and the end (1, 5, 15 min), if known.
    pub load_average: [Option<String>; 2],
    /// A note on the slice figures (their sweep settings), if any.
    pub slices_note: Option<String>,
}

/// `/proc/loadavg` (1, 5, 15 min), if readable: the load of the machine, for the report.
pub fn load_average() -> Option<String> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    Some(
        text.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(", "),
    )
}

/// The design files: (file name, title, record).
pub fn design_choices(result: &SearchResult) -> Vec<(&'static str, &'static str, &Record)> {
    let mut out = Vec::new();
    if let Some(r) = result.best_composite() {
        out.push(("best_composite.ron", "best composite", r));
    }
    let names = [
        ("pareto_max_volume.ron", "Pareto: max volume"),
        ("pareto_max_isotropy.ron", "Pareto: max isotropy"),
        ("pareto_max_margin.ron", "Pareto: max margin"),
    ];
    for (k, (file, title)) in names.into_iter().enumerate() {
        if let Some(r) = result.pareto_extreme(k) {
            out.push((file, title, r));
        }
    }
    out
}

/// The RON text of a candidate's design with a comment header, or `None` if the record
/// does not map to a valid design (never for a feasible record).
pub fn design_file(setup: &Setup, record: &Record, title: &str) -> Option<String> {
    let design = setup.space.design(&record.x).ok()?;
    let mut head = format!(
        "// tdpcr-optim: {title}, candidate {} (generation {}) of {} (seed {}).\n",
        record.id,
        record.generation.map_or("-".into(), |g| g.to_string()),
        setup.config_path.display(),
        setup.config.seed
    );
    if let Some(m) = record.outcome.measures() {
        let _ = writeln!(
            head,
            "// Coarse-sweep objectives: volume {:.1} cm³, mean rcond(J_p) {:.4}, singularity margin {:.3}; composite {:.4}.",
            m.volume_non_singular * 1e6,
            m.rcond_j_p.mean,
            m.singularity_margin,
            record.composite.unwrap_or(0.0)
        );
    }
    Some(format!("{head}{}\n", design.to_ron_string()))
}

/// `pareto.csv`: columns `id, role, best_composite, generation`, the parameters, the three
/// Pareto objectives, `composite`, then every other measure (SI units; volumes in m³).
/// Rows: the reference (`role` = reference), then the front by id (`pareto`).
pub fn pareto_csv(setup: &Setup, result: &SearchResult) -> String {
    let params: Vec<&str> = setup
        .space
        .bounds()
        .iter()
        .map(|b| b.parameter.name())
        .collect();
    let others: Vec<Objective> = Objective::ALL
        .into_iter()
        .filter(|o| !PARETO_OBJECTIVES.contains(o))
        .collect();
    let mut header: Vec<String> = ["id", "role", "best_composite", "generation"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    header.extend(params.iter().map(|s| s.to_string()));
    header.extend(PARETO_OBJECTIVES.iter().map(|o| o.name().to_string()));
    header.push("composite".into());
    header.extend(others.iter().map(|o| o.name().to_string()));
    let mut out = header.join(",") + "\n";
    let best = result.best_composite().map(|r| r.id);
    let rows = std::iter::once((&result.reference, "reference"))
        .chain(result.pareto_front().into_iter().map(|r| (r, "pareto")));
    for (r, role) in rows {
        let Some(m) = r.outcome.measures() else {
            continue;
        };
        let mut cells = vec![
            r.id.to_string(),
            role.to_string(),
            u8::from(Some(r.id) == best && role != "reference").to_string(),
            r.generation.map_or(String::new(), |g| g.to_string()),
        ];
        cells.extend(
            params
                .iter()
                .map(|p| r.parameters.get(*p).copied().unwrap_or(0.0).to_string()),
        );
        cells.extend(PARETO_OBJECTIVES.iter().map(|o| o.value(m).to_string()));
        cells.push(r.composite.unwrap_or(0.0).to_string());
        cells.extend(others.iter().map(|o| o.value(m).to_string()));
        out += &(cells.join(",") + "\n");
    }
    out
}

/// A parameter value with its unit for people: angles in degrees, lengths in mm.
fn show_parameter(p: DesignParameter, v: f64) -> String {
    match p.unit() {
        "rad" => format!("{:.2}°", v.to_degrees()),
        "m" => format!("{:.2} mm", v * 1e3),
        _ => format!("{v:.3} N"),
    }
}

/// A measure for people (volume in cm³, rconds with 4 significant digits).
fn show_measure(o: Objective, v: f64) -> String {
    let x = v * o.display_factor();
    match o {
        Objective::WorkspaceVolume | Objective::ReachableVolume => format!("{x:.1}"),
        Objective::MinTension => format!("{x:.3}"),
        _ if x != 0.0 && x.abs() < 1e-3 => format!("{x:.3e}"),
        _ => format!("{x:.4}"),
    }
}

/// For each feasible candidate min_k o_k / ref_k over the Pareto objectives: ≥ 1 with a
/// strict improvement means it dominates. Returns the candidate with the largest value.
fn closest_to_dominating(result: &SearchResult) -> Option<(&Record, [f64; 3])> {
    let reference = result.reference.outcome.measures()?.pareto();
    result
        .candidates
        .iter()
        .filter_map(|r| {
            let p = r.outcome.measures()?.pareto();
            let ratios = [0, 1, 2].map(|k| {
                if reference[k] > 0.0 {
                    p[k] / reference[k]
                } else if p[k] >= reference[k] {
                    1.0
                } else {
                    0.0
                }
            });
            Some((r, ratios))
        })
        .fold(None, |best: Option<(&Record, [f64; 3])>, (r, q)| {
            let score = |q: &[f64; 3]| q.iter().copied().fold(f64::INFINITY, f64::min);
            match best {
                Some((_, b)) if score(&b) >= score(&q) => best,
                _ => Some((r, q)),
            }
        })
}

fn stats(mut xs: Vec<f64>) -> Option<(f64, f64, f64, f64)> {
    if xs.is_empty() {
        return None;
    }
    xs.sort_by(f64::total_cmp);
    let mean = xs.iter().sum::<f64>() / xs.len() as f64;
    Some((mean, xs[xs.len() / 2], xs[0], xs[xs.len() - 1]))
}

/// The Markdown report.
pub fn report_markdown(
    setup: &Setup,
    result: &SearchResult,
    slices: &[SliceSet],
    ctx: &ReportContext,
) -> String {
    let c = &setup.config;
    let mut md = String::new();
    let w = &mut md;
    let _ = writeln!(w, "# Design optimization report\n");
    let _ = write!(
        w,
        "Config `{}` (seed {}), base design `{}` (the reference).",
        setup.config_path.display(),
        c.seed,
        c.base_design.display(),
    );
    if !ctx.command.is_empty() {
        let _ = write!(w, " Command: `{}`.", ctx.command);
    }
    let _ = writeln!(w, "\n");

    // Outcome.
    let dominating = result.dominating_reference();
    let _ = writeln!(w, "## Outcome\n");
    if result.reference.outcome.measures().is_none() {
        let _ = writeln!(
            w,
            "The reference design is infeasible under these evaluation settings ({}); every feasible candidate improves on it.\n",
            infeasible_reason(&result.reference)
        );
    } else if !dominating.is_empty() {
        let ids: Vec<String> = dominating
            .iter()
            .take(12)
            .map(|r| format!("#{}", r.id))
            .collect();
        let _ = writeln!(
            w,
            "**{} candidate(s) Pareto-dominate the reference** on non-singular workspace volume, mean rcond(J_p) and singularity margin (at least as good on all three, better on one): {}{}.\n",
            dominating.len(),
            ids.join(", "),
            if dominating.len() > 12 { ", ..." } else { "" }
        );
    } else {
        let _ = write!(w, "**No candidate Pareto-dominates the reference.**");
        if let Some((r, q)) = closest_to_dominating(result) {
            let _ = writeln!(
                w,
                " The closest (largest smallest ratio to the reference), #{}, reaches {:.1} % of the reference's volume, {:.1} % of its mean rcond(J_p) and {:.1} % of its singularity margin.\n",
                r.id,
                100.0 * q[0],
                100.0 * q[1],
                100.0 * q[2]
            );
        } else {
            let _ = writeln!(w, " No candidate was feasible.\n");
        }
    }

    // Run.
    let feasible = result
        .candidates
        .iter()
        .filter(|r| r.composite.is_some())
        .count();
    let mut reasons: BTreeMap<&str, usize> = BTreeMap::new();
    for r in &result.candidates {
        if let crate::objectives::Outcome::Infeasible { reason } = &r.outcome {
            *reasons.entry(reason.kind()).or_default() += 1;
        }
    }
    let reasons: Vec<String> = reasons.iter().map(|(k, n)| format!("{n} {k}")).collect();
    let _ = writeln!(w, "## Run\n\n| | |\n|---|---|");
    let _ = writeln!(w, "| termination | {} |", result.termination);
    let _ = writeln!(
        w,
        "| candidates | {} ({} evaluated in this invocation, {} from the log of an earlier one) |",
        result.candidates.len(),
        result.evaluated,
        result.from_log
    );
    let _ = writeln!(
        w,
        "| feasible | {feasible}; infeasible: {} |",
        if reasons.is_empty() {
            "none".into()
        } else {
            reasons.join(", ")
        }
    );
    let _ = writeln!(
        w,
        "| CMA-ES | population {}, {} complete generations, σ₀ = {} |",
        c.population_size(),
        result.generations,
        c.initial_step
    );
    let _ = writeln!(
        w,
        "| wall time of this invocation | {:.0} s |",
        result.wall_time_s
    );
    if let Some((mean, median, min, max)) =
        stats(result.candidates.iter().map(|r| r.eval_time_s).collect())
    {
        let _ = writeln!(
            w,
            "| time per evaluation | mean {mean:.2} s, median {median:.2} s, min {min:.2} s, max {max:.2} s (wall time of each, with other evaluations running in parallel) |"
        );
    }
    if result.evaluated > 0 && result.wall_time_s > 0.0 {
        let _ = writeln!(
            w,
            "| throughput | {:.1} evaluations per minute |",
            60.0 * result.evaluated as f64 / result.wall_time_s
        );
    }
    let _ = writeln!(
        w,
        "| reference evaluation | {:.2} s |",
        result.reference.eval_time_s
    );
    if ctx.threads > 0 {
        let _ = writeln!(w, "| threads | {} |", ctx.threads);
    }
    if let [Some(a), Some(b)] = &ctx.load_average {
        let _ = writeln!(w, "| load average (1, 5, 15 min) | start {a}; end {b} |");
    }
    let _ = writeln!(w);

    // Table.
    let choices = design_choices(result);
    let _ = writeln!(w, "## Reference vs best\n");
    let _ = write!(w, "| | reference");
    for (file, title, r) in &choices {
        let _ = write!(w, " | {title} (#{}, [{file}]({file}))", r.id);
    }
    let _ = write!(w, " |\n|---|---:");
    for _ in &choices {
        let _ = write!(w, "|---:");
    }
    let _ = writeln!(w, "|");
    let records: Vec<&Record> = std::iter::once(&result.reference)
        .chain(choices.iter().map(|c| c.2))
        .collect();
    let row = |w: &mut String, label: String, cell: &dyn Fn(&Record) -> String| {
        let _ = write!(w, "| {label}");
        for r in &records {
            let _ = write!(w, " | {}", cell(r));
        }
        let _ = writeln!(w, " |");
    };
    row(w, "composite".into(), &|r| {
        r.composite.map_or("–".into(), |c| format!("{c:.4}"))
    });
    let mut objectives: Vec<Objective> = PARETO_OBJECTIVES.to_vec();
    objectives.extend(
        Objective::ALL
            .into_iter()
            .filter(|o| !PARETO_OBJECTIVES.contains(o)),
    );
    for o in objectives {
        let bold = PARETO_OBJECTIVES.contains(&o);
        let label = if bold {
            format!("**{}**", o.label())
        } else {
            o.label().to_string()
        };
        row(w, label, &|r| {
            r.outcome
                .measures()
                .map_or_else(|| "infeasible".into(), |m| show_measure(o, o.value(m)))
        });
    }
    for b in setup.space.bounds() {
        let p = b.parameter;
        row(
            w,
            format!(
                "{} {} (bounds {} – {})",
                p.symbol(),
                p.name(),
                show_parameter(p, b.min),
                show_parameter(p, b.max)
            ),
            &|r| {
                r.parameters
                    .get(p.name())
                    .map_or("–".into(), |&v| show_parameter(p, v))
            },
        );
    }
    let _ = writeln!(
        w,
        "\nVolumes in cm³ (1 cm³ = 1e-6 m³). The composite is {} over {}.\n",
        match result.composite.aggregation() {
            crate::config::Aggregation::Sum => "Σ w·r / Σ w, r = v/v_ref (`Sum`)".to_string(),
            crate::config::Aggregation::Min => format!(
                "min r^(w / max w) + {} (Σ w·r / Σ w − 1), r = v/v_ref (`Min`: the worst ratio; the mean only breaks ties)",
                crate::objectives::MIN_TIE_BREAK
            ),
        },
        result
            .composite
            .terms()
            .iter()
            .map(|(o, wt, s)| format!("{} (w = {wt}, v_ref = {})", o.name(), show_measure(*o, *s)))
            .collect::<Vec<_>>()
            .join(", ")
    );

    // Front.
    let front = result.pareto_front();
    let _ = writeln!(
        w,
        "## Pareto front\n\n{} non-dominated feasible candidates (all in [pareto.csv](pareto.csv)).\n\n![Pareto front](pareto.svg)\n\n![Search progress](progress.svg)\n",
        front.len()
    );

    // Slices.
    if !slices.is_empty() {
        let _ = writeln!(w, "## Workspace slices\n");
        if let Some(note) = &ctx.slices_note {
            let _ = writeln!(w, "{note}\n");
        }
        let mut all: Vec<&String> = Vec::new();
        for s in slices {
            for (n, _) in &s.files {
                if !all.contains(&n) {
                    all.push(n);
                }
            }
        }
        // By the slice height in the name (`reach_z-0.060.svg`).
        let height = |n: &str| {
            n.trim_end_matches(".svg")
                .rsplit_once("_z")
                .and_then(|(_, z)| z.parse::<f64>().ok())
                .unwrap_or(0.0)
        };
        all.sort_by(|a, b| height(a).total_cmp(&height(b)).then(a.cmp(b)));
        let _ = write!(w, "| figure");
        for s in slices {
            let _ = write!(w, " | {}", s.label);
        }
        let _ = write!(w, " |\n|---");
        for _ in slices {
            let _ = write!(w, "|---");
        }
        let _ = writeln!(w, "|");
        for n in all.into_iter().filter(|n| n.starts_with("reach_")) {
            let _ = write!(w, "| {n}");
            for s in slices {
                if s.files.iter().any(|(m, _)| m == n) {
                    let _ = write!(w, " | ![]({}/{n})", s.dir);
                } else {
                    let _ = write!(w, " | (no cells)");
                }
            }
            let _ = writeln!(w, " |");
        }
        let _ = writeln!(
            w,
            "\nThe rcond and tension maps of each slice are beside these files (`rcond_z*.svg`, `tension_z*.svg`).\n"
        );
        fine_table(w, slices);
    }

    // Evaluation.
    let e = &c.evaluation;
    let _ = writeln!(
        w,
        "## Evaluation\n\nEach design: a workspace sweep (MODEL.md §6) per orientation with Δ = {} mm, φ = {} rad, planes in z ∈ [{}, {}] m, {} Newton iterations per step, tolerance {:e}; orientations (rotation vectors, rad): {:?}. Measures over the reachable cells (paper Tab. III); the singularity margin is the fraction of reachable cells clear of Type I, Type II and leg singularities (flags at the library's default thresholds). A design is infeasible when its parameters break a design rule, its home configuration does not solve, or the home configuration is outside the actuation limits or collides.",
        e.step * 1e3,
        e.angle_step,
        e.z_range.0,
        e.z_range.1,
        e.max_iterations,
        e.tolerance,
        e.orientations
    );
    md
}

/// The Pareto objectives of the slice sweeps (a finer resolution than the search's), and
/// whether each design dominates the first (the reference) there.
fn fine_table(w: &mut String, slices: &[SliceSet]) {
    let with: Vec<(&SliceSet, &crate::objectives::Measures)> = slices
        .iter()
        .filter_map(|s| s.measures.as_ref().map(|m| (s, m)))
        .collect();
    if with.len() < 2 {
        return;
    }
    let _ = write!(w, "The same objectives from these finer sweeps:\n\n| |");
    for (s, _) in &with {
        let _ = write!(w, " {} |", s.label);
    }
    let _ = write!(w, "\n|---|");
    for _ in &with {
        let _ = write!(w, "---:|");
    }
    let _ = writeln!(w);
    for o in PARETO_OBJECTIVES
        .into_iter()
        .chain([Objective::ReachableVolume])
    {
        let _ = write!(w, "| {} |", o.label());
        for (_, m) in &with {
            let _ = write!(w, " {} |", show_measure(o, o.value(m)));
        }
        let _ = writeln!(w);
    }
    let reference = with[0].1.pareto();
    let _ = write!(w, "| dominates the {} |", with[0].0.label);
    for (_, m) in &with {
        let d = crate::pareto::dominates(&m.pareto(), &reference);
        let _ = write!(w, " {} |", if d { "yes" } else { "no" });
    }
    let _ = writeln!(w, "\n");
}

fn infeasible_reason(r: &Record) -> String {
    match &r.outcome {
        crate::objectives::Outcome::Infeasible { reason } => reason.to_string(),
        crate::objectives::Outcome::Feasible(_) => "feasible".into(),
    }
}

/// Writes every output file into `dir` and returns their paths.
///
/// # Errors
/// [`OptimError::Io`].
pub fn write_outputs(
    dir: &Path,
    setup: &Setup,
    result: &SearchResult,
    slices: &[SliceSet],
    ctx: &ReportContext,
) -> Result<Vec<PathBuf>, OptimError> {
    let mut written = Vec::new();
    let mut put = |name: &str, text: &str| -> Result<(), OptimError> {
        let path = dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|source| OptimError::io(parent, source))?;
        }
        write_atomically(&path, text.as_bytes())?;
        written.push(path);
        Ok(())
    };
    for (file, title, record) in design_choices(result) {
        if let Some(text) = design_file(setup, record, title) {
            put(file, &text)?;
        }
    }
    put("pareto.csv", &pareto_csv(setup, result))?;
    put("pareto.svg", &pareto_figure(result))?;
    put("progress.svg", &progress_figure(result))?;
    for s in slices {
        for (name, svg) in &s.files {
            put(&format!("{}/{name}", s.dir), svg)?;
        }
    }
    let mut md = report_markdown(setup, result, slices, ctx);
    if let Some(page) = crate::design_view::designs_page(setup, result) {
        put("designs.html", &page)?;
        md.push_str(
            "\n## 3D view\n\nThe reference and the best design side by side in their home \
             configurations: [designs.html](designs.html) (opens offline).\n",
        );
    }
    put("report.md", &md)?;
    Ok(written)
}
