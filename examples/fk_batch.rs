use tdpcr::Tdpcr;
use tdpcr::kinetostatics::*;
use tdpcr::rod::Wrench;
fn main() {
    let d = Tdpcr::from_ron_file("designs/lilge2022.ron").unwrap();
    let mut s = Solver::new(&d);

    let mut seed: u64 = 42;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 11) as f64) / ((1u64 << 53) as f64)
    };
    let (mut ok, mut its, mut times) = (0, vec![], vec![]);
    for _ in 0..30 {
        let common = (rnd() * 2.0 - 1.0) * 0.08;
        let q: Vec<f64> = (0..6)
            .map(|k| {
                if k % 2 == 0 {
                    (rnd() * 2.0 - 1.0) * 0.01
                } else {
                    common + (rnd() * 2.0 - 1.0) * 0.02
                }
            })
            .collect();
        match s.solve_fk(&q, &Wrench::default(), None) {
            Ok(sol) => {
                ok += 1;
                its.push(sol.report.iterations);
                times.push(sol.solve_time_us);
            }
            Err(e) => println!("{q:.4?}: {e}"),
        }
    }
    its.sort();
    times.sort_by(|a, b| a.total_cmp(b));
    println!(
        "converged {ok}/30, median its {}, median time {:.0} us",
        its[its.len() / 2],
        times[times.len() / 2]
    );
    // warm steps
    let home = s.solve_fk(&[0.0; 6], &Wrench::default(), None).unwrap();
    let mut state = home.state.clone();
    let mut its = vec![];
    let mut times = vec![];
    for k in 1..200 {
        let t = k as f64 * 0.001;
        let pose = tdpcr::model::Pose {
            position: home.state.pose().position
                + nalgebra::Vector3::new(
                    0.03 * (t * 3.0).sin(),
                    0.03 * (1.0 - (t * 3.0).cos()),
                    -0.01 * t,
                ),
            rotation: home.state.pose().rotation,
        };
        match s.solve_ik(&pose, &Wrench::default(), Some(&state)) {
            Ok(sol) => {
                its.push(sol.report.iterations);
                times.push(sol.solve_time_us);
                state = sol.state;
            }
            Err(e) => {
                println!("step {k}: {e}");
                break;
            }
        }
    }
    its.sort();
    times.sort_by(|a, b| a.total_cmp(b));
    println!(
        "warm IK: {} steps, median its {}, median {:.0} us, max {:.0} us",
        its.len(),
        its[its.len() / 2],
        times[times.len() / 2],
        times[times.len() - 1]
    );
}
