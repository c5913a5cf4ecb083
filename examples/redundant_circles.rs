//! Warm IK of the 9-DoF design along circles of the platform: from home, a spiral out to
//! the circle over one lap, then one lap on it, in steps of about 1 mm, the circle's
//! plane tilted about x (the platform too); prints the steps that fail and why, the
//! residual evaluations of the converged steps, the largest change of q in a step and
//! the steps' `solve_time_us` (MODEL.md "Least-norm steps across tendon kinks"); with
//! the environment variable `STEPS` set, each converged step's evaluations, time and q
//! on standard error: `redundant_circles [radius mm, default 10] [tilt deg, default 0]
//! [least_norm|least_norm_gauss_newton|within_limits, default least_norm]`.
use nalgebra::{Rotation3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::kinetostatics::{Objective, Redundancy, Solver};
use tdpcr::model::Pose;
use tdpcr::rod::Wrench;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let radius = 1e-3
        * args
            .get(1)
            .and_then(|s| s.parse::<f64>().ok())
            .unwrap_or(10.0);
    let tilt = args
        .get(2)
        .and_then(|s| s.parse::<f64>().ok())
        .unwrap_or(0.0)
        .to_radians();
    let rule = args.get(3).map(String::as_str).unwrap_or("least_norm");
    let design = Tdpcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/lilge2022_redundant.ron"
    ))
    .unwrap();
    let mut solver = Solver::new(&design).expect("valid design");
    solver.least_norm_gauss_newton = rule == "least_norm_gauss_newton";
    if rule == "within_limits" {
        solver.redundancy = Redundancy::WithinLimits(Objective::LeastChange);
    }
    let w = Wrench::default();
    let home = solver.solve_ik(&Pose::identity(), &w, None).unwrap().state;
    let rotation = Rotation3::from_axis_angle(&Vector3::x_axis(), tilt).into_inner();
    let steps = (std::f64::consts::TAU * radius / 1e-3).ceil() as usize;
    let mut state = home.clone();
    let (mut failed, mut evaluations, mut largest_dq) = (0, 0, 0.0_f64);
    let mut times = Vec::new();
    for k in 1..=2 * steps {
        let t = k as f64 / steps as f64;
        let r = radius * t.min(1.0);
        let angle = std::f64::consts::TAU * t;
        let pose = Pose {
            position: Vector3::new(r * angle.cos(), r * angle.sin(), 0.0),
            rotation: rotation * home.pose().rotation,
        };
        match solver.solve_ik(&pose, &w, Some(&state)) {
            Ok(s) => {
                evaluations += s.report.residual_evaluations;
                times.push(s.solve_time_us);
                if std::env::var_os("STEPS").is_some() {
                    eprintln!(
                        "{k} {} {:.0} {:?}",
                        s.report.residual_evaluations, s.solve_time_us, s.state.q
                    );
                }
                let dq = s
                    .state
                    .q
                    .iter()
                    .zip(&state.q)
                    .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
                largest_dq = largest_dq.max(dq);
                state = s.state;
            }
            Err(e) => {
                failed += 1;
                println!("step {k} (lap {}): {e}", 1 + (k - 1) / steps);
            }
        }
    }
    times.sort_by(f64::total_cmp);
    let (median, max) = (times[times.len() / 2], times[times.len() - 1]);
    println!(
        "radius {:.0} mm, tilt {:.0}°: {failed} of {} steps failed, {evaluations} evaluations, largest |Δq| of a step {:.3} mm; solve_time_us median {median:.0}, max {max:.0}",
        radius * 1e3,
        tilt.to_degrees(),
        2 * steps,
        largest_dq * 1e3
    );
}
