//! Runs one kind of boundary Jacobian evaluation many times at a solved configuration
//! (for instruction counting under callgrind):
//! `boundary_cost {6dof|9dof} {residual|exact|fd_forward|fd_central} [repetitions, default 200]`.
use nalgebra::DVector;
use tdpcr::Tdpcr;
use tdpcr::boundary::{
    BoundaryJacobians, BoundaryScratch, FiniteDifference, boundary_derivatives,
    boundary_derivatives_fd, boundary_residual,
};
use tdpcr::kinetostatics::Solver;
use tdpcr::model::Model;
use tdpcr::rod::Wrench;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (file, q) = match args.get(1).map(String::as_str) {
        Some("9dof") => ("lilge2022_redundant.ron", vec![0.0; 9]),
        _ => (
            "lilge2022.ron",
            vec![0.004, 0.02, -0.003, -0.01, 0.002, 0.03],
        ),
    };
    let d = Tdpcr::from_ron_file(format!("{}/designs/{file}", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let model = Model::new(&d);
    let mut solver = Solver::new(&d).expect("valid design");
    let state = solver.solve_fk(&q, &Wrench::default(), None).unwrap().state;
    let pose = state.pose();
    let wrench = solver.total_wrench(&Wrench::default());
    let p = state.boundary_point(&pose, &wrench);
    let mut sc = BoundaryScratch::new(&model);
    let mut jac = BoundaryJacobians::new(&model);
    let mut r = DVector::zeros(model.n_residuals());
    let kind = args.get(2).map(String::as_str).unwrap_or("exact");
    let repetitions: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(200);
    for _ in 0..repetitions {
        // Every evaluation integrates (one at the last one's leg starts would reuse it).
        sc.forget_integration();
        match kind {
            "none" => {}
            "residual" => boundary_residual(&model, &mut sc, &p, &mut r).unwrap(),
            "exact" => boundary_derivatives(&model, &mut sc, &p, &mut r, &mut jac).unwrap(),
            "fd_forward" => boundary_derivatives_fd(
                &model,
                &mut sc,
                &p,
                FiniteDifference::Forward,
                &mut r,
                &mut jac,
            )
            .unwrap(),
            _ => boundary_derivatives_fd(
                &model,
                &mut sc,
                &p,
                FiniteDifference::Central,
                &mut r,
                &mut jac,
            )
            .unwrap(),
        }
    }
    println!("{}", r.norm());
}
