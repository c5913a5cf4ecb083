//! The numbers of docs/ANALYSIS.md: the four ellipsoids of the reference design at the
//! paper's initial configuration x_ee = I (IK) and at q = 0 (FK), and rcond statistics of
//! J_p, J_o, C_p, C_o over a coarse z = 0 slice of the translational workspace (R_ee = I;
//! rays every 15° from the origin, 5 mm steps, warm-started IK, until a solve fails or q
//! leaves its limits).
//!
//! `cargo run --release --example analysis_fig8`

use nalgebra::{Matrix3, Vector3};
use tdpcr::Tdpcr;
use tdpcr::analysis::{Analysis, AnalysisSettings, Ellipsoid};
use tdpcr::kinetostatics::Solver;
use tdpcr::model::Pose;
use tdpcr::rod::Wrench;

fn show(name: &str, unit: &str, e: &Ellipsoid) {
    let axes: Vec<String> = (0..3)
        .map(|k| {
            let d = e.directions[k];
            format!(
                "{:.4} along ({:+.2}, {:+.2}, {:+.2})",
                e.semi_axes[k], d[0], d[1], d[2]
            )
        })
        .collect();
    println!("  {name} [{unit}]: {}", axes.join("; "));
}

fn report(title: &str, a: &Analysis) {
    println!("{title}");
    show("J_p", "m/m", &a.ellipsoids.j_p);
    show("J_o", "rad/m", &a.ellipsoids.j_o);
    show("C_p", "m/N", &a.ellipsoids.c_p);
    show("C_o", "rad/(N m)", &a.ellipsoids.c_o);
    let r = &a.rcond;
    println!(
        "  rcond J_p {:.4}, J_o {:.4}, C_p {:.4}, C_o {:.4}; [B_x B_u] {:.3e}, [B_q B_u] {:.3e}, B_u {:.3e}",
        r.j_p, r.j_o, r.c_p, r.c_o, r.b_xu, r.b_qu, r.b_u
    );
}

fn main() {
    let design = Tdpcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/lilge2022.ron"
    ))
    .expect("bundled design");
    let mut solver = Solver::new(&design).expect("valid design");
    let w = Wrench::default();
    let settings = AnalysisSettings::default();
    let home = solver
        .solve_ik(&Pose::identity(), &w, None)
        .expect("IK at x_ee = I");
    let a = solver.analyze(&home.state, &w, &settings).unwrap();
    report("x_ee = I (IK; the paper's Fig. 8, top row)", &a);
    let fk = solver.solve_fk(&[0.0; 6], &w, None).expect("FK at q = 0");
    println!("q = 0 (FK): platform at z = {:.4} m", fk.state.position[2]);
    let b = solver.analyze(&fk.state, &w, &settings).unwrap();
    report("q = 0 (FK)", &b);

    // Coarse z = 0 slice.
    let limits = &design.actuation_limits;
    let within = |q: &[f64]| {
        q.iter().enumerate().all(|(j, x)| {
            x.abs()
                <= if j % 2 == 1 {
                    limits.base_translation
                } else {
                    limits.tendon_displacement
                }
        })
    };
    let mut values: Vec<[f64; 4]> = vec![[a.rcond.j_p, a.rcond.j_o, a.rcond.c_p, a.rcond.c_o]];
    let mut type_ii = 0;
    for ray in 0..24 {
        let phi = ray as f64 * 15f64.to_radians();
        let mut state = home.state.clone();
        for step in 1.. {
            let p = Vector3::new(phi.cos(), phi.sin(), 0.0) * (0.005 * step as f64);
            let pose = Pose {
                position: p,
                rotation: Matrix3::identity(),
            };
            let Ok(sol) = solver.solve_ik(&pose, &w, Some(&state)) else {
                break;
            };
            if !within(&sol.state.q) {
                break;
            }
            state = sol.state;
            let Ok(an) = solver.analyze(&state, &w, &settings) else {
                break;
            };
            type_ii += usize::from(an.singularity.type_ii);
            values.push([an.rcond.j_p, an.rcond.j_o, an.rcond.c_p, an.rcond.c_o]);
        }
    }
    println!(
        "z = 0 slice: {} reachable points ({} flagged Type II)",
        values.len(),
        type_ii
    );
    for (k, name) in ["J_p", "J_o", "C_p", "C_o"].iter().enumerate() {
        let v: Vec<f64> = values.iter().map(|x| x[k]).collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let max = v.iter().copied().fold(0.0, f64::max);
        let min = v.iter().copied().fold(f64::INFINITY, f64::min);
        println!("  rcond {name}: mean {mean:.4}, max {max:.4}, min {min:.3e}");
    }
}
