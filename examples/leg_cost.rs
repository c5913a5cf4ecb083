//! Runs one kind of leg integration many times (for instruction counting under callgrind).
use nalgebra::Vector3;
use tdpcr::Tdcr;
use tdpcr::design::MAX_TENDONS;
use tdpcr::rod::*;
fn main() {
    let mode = std::env::args().nth(1).unwrap_or_default();
    let robot = Tdcr::from_ron_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/designs/tdcr_one_segment.ron"
    ))
    .unwrap();
    let model = LegModel::new(&robot.leg, Vector3::new(0.0, 0.0, -9.81));
    let mut t = [0.0; MAX_TENDONS];
    t[0] = 3.2;
    let start = LegStart {
        base: Frame::identity(),
        u0: Vector3::new(0.3, 6.0, 0.0),
        v0: Vector3::new(0.0, 0.0, 0.99992),
        tensions: t,
    };
    let mut sc = LegScratch::new();
    let mut e = LegEnd::zeros();
    let mut s = LegSensitivities::new(8);
    for _ in 0..1000 {
        if mode == "sens" {
            integrate_leg_with_sensitivities(&model, &start, &mut sc, &mut e, &mut s, None)
                .unwrap();
        } else {
            integrate_leg(&model, &start, &mut sc, &mut e, None).unwrap();
        }
    }
    println!("{}", e.p.x);
}
