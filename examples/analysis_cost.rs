//! Runs `analyze_blocks` many times at the bench's configuration (for instruction
//! counting under callgrind), or prints every output of the analysis at a few
//! configurations (for comparing two versions):
//! `analysis_cost {6dof|9dof} [repetitions, default 200]` or `analysis_cost dump`.
use tdpcr::Tdpcr;
use tdpcr::analysis::{AnalysisSettings, analyze_blocks, condition_blocks};
use tdpcr::kinetostatics::Solver;
use tdpcr::rod::Wrench;

fn design(file: &str) -> Tdpcr {
    Tdpcr::from_ron_file(format!("{}/designs/{file}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

/// Dense-SVD rconds of [B_x B_u], [B_q B_u], B_u, raw then unit-scaled.
fn dense_rconds(model: &tdpcr::model::Model, b: &tdpcr::boundary::BoundaryJacobians) -> [f64; 6] {
    use nalgebra::DMatrix;
    use tdpcr::analysis::{UnitScaling, rcond::rcond};
    let s = UnitScaling::new(model);
    let (n, nq, ny) = (b.b_x.nrows(), b.b_q.ncols(), b.b_u.ncols());
    let mut out = [0.0; 6];
    for scaled in [false, true] {
        let r = |i: usize| if scaled { 1.0 / s.row(i) } else { 1.0 };
        let cu = |j: usize| if scaled { s.leg_unknown(j) } else { 1.0 };
        let cx = |j: usize| if scaled { s.pose(j) } else { 1.0 };
        let cq = |j: usize| if scaled { s.actuation(j) } else { 1.0 };
        let m_x = DMatrix::from_fn(n, n, |i, j| {
            r(i) * if j < 6 {
                b.b_x[(i, j)] * cx(j)
            } else {
                b.b_u[(i, j - 6)] * cu(j - 6)
            }
        });
        let m_q = DMatrix::from_fn(n, nq + ny, |i, j| {
            r(i) * if j < nq {
                b.b_q[(i, j)] * cq(j)
            } else {
                b.b_u[(i, j - nq)] * cu(j - nq)
            }
        });
        let m_u = DMatrix::from_fn(n, ny, |i, j| r(i) * b.b_u[(i, j)] * cu(j));
        let k = if scaled { 3 } else { 0 };
        out[k] = rcond(&m_x);
        out[k + 1] = rcond(&m_q);
        out[k + 2] = rcond(&m_u);
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let settings = AnalysisSettings::default();
    if args.get(1).map(String::as_str) == Some("dump") {
        let six = [
            vec![0.004, 0.02, -0.003, -0.01, 0.002, 0.03],
            vec![0.0; 6],
            vec![-0.006, 0.01, 0.008, -0.02, 0.0, 0.015],
        ];
        let nine = [
            vec![0.0; 9],
            vec![0.003, -0.002, 0.01, 0.001, 0.004, -0.01, -0.002, 0.0, 0.02],
        ];
        let wrenches = [
            Wrench::default(),
            Wrench {
                force: nalgebra::Vector3::new(0.5, -0.3, -1.0),
                moment: nalgebra::Vector3::new(0.01, 0.02, -0.01),
            },
        ];
        for (file, qs) in [
            ("lilge2022.ron", &six[..]),
            ("lilge2022_redundant.ron", &nine[..]),
        ] {
            let d = design(file);
            let mut solver = Solver::new(&d).unwrap();
            for q in qs {
                for w in &wrenches {
                    let Ok(sol) = solver.solve_fk(q, w, None) else {
                        println!("{file} {q:?}: no FK");
                        continue;
                    };
                    let state = sol.state;
                    let (_r, blocks) = solver.blocks_at(&state, w).unwrap();
                    let blocks = blocks.clone();
                    let model = solver.model().clone();
                    let a = analyze_blocks(&model, &blocks, &state.y_u, &settings).unwrap();
                    let c = condition_blocks(&model, &blocks, &state.y_u, &settings).unwrap();
                    println!("CASE {file} {q:?} {w:?}");
                    println!("{a:?}");
                    println!("{c:?}");
                    let dense = dense_rconds(&model, &blocks);
                    println!(
                        "DENSE {:?} {:?} {:?} {:?} {:?} {:?}",
                        (a.rcond.b_xu / dense[0] - 1.0),
                        (a.rcond.b_qu / dense[1] - 1.0),
                        (a.rcond.b_u / dense[2] - 1.0),
                        (a.rcond_scaled.b_xu / dense[3] - 1.0),
                        (a.rcond_scaled.b_qu / dense[4] - 1.0),
                        (a.rcond_scaled.b_u / dense[5] - 1.0),
                    );
                }
            }
        }
        return;
    }
    let (file, q) = match args.get(1).map(String::as_str) {
        Some("9dof") => ("lilge2022_redundant.ron", vec![0.0; 9]),
        _ => (
            "lilge2022.ron",
            vec![0.004, 0.02, -0.003, -0.01, 0.002, 0.03],
        ),
    };
    let repetitions: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(200);
    let d = design(file);
    let mut solver = Solver::new(&d).unwrap();
    let state = solver.solve_fk(&q, &Wrench::default(), None).unwrap().state;
    let (_r, blocks) = solver.blocks_at(&state, &Wrench::default()).unwrap();
    let blocks = blocks.clone();
    let model = solver.model().clone();
    let mut sum = 0.0;
    for _ in 0..repetitions {
        let a =
            analyze_blocks(&model, std::hint::black_box(&blocks), &state.y_u, &settings).unwrap();
        sum += a.rcond.b_xu;
    }
    println!("{sum:e}");
}
