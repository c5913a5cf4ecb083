//! The short library examples run as they are shown to users.

#[path = "../examples/controller_loop.rs"]
mod controller_loop;
#[path = "../examples/solve_fk.rs"]
mod solve_fk;

#[test]
fn solve_fk_runs() {
    solve_fk::main().unwrap();
}

#[test]
fn controller_loop_runs() {
    controller_loop::main().unwrap();
}
