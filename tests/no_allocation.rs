//! The hot paths do not allocate: leg integration (with and without sensitivities), the
//! Newton loop and a configuration's measures ([`Solver::condition`], after its first
//! call on a thread). A counting global allocator counts the allocations of the thread that
//! measures (the test harness's own thread may allocate meanwhile: under load it did, and
//! the count of every thread then read 4 where the work allocated nothing).

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::{DMatrix, DVector, Vector3};
use tdpcr::analysis::AnalysisSettings;
use tdpcr::design::{MAX_TENDONS, Tdpcr};
use tdpcr::error::SolveError;
use tdpcr::kinetostatics::Solver;
use tdpcr::newton::{self, NewtonScratch, NewtonSettings, NonlinearSystem};
use tdpcr::rod::{
    Frame, LegEnd, LegModel, LegScratch, LegSensitivities, LegShape, LegStart, Wrench,
    integrate_leg, integrate_leg_with_sensitivities,
};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread's allocations are counted (const-initialized: reading it
    /// never allocates).
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTED.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations this thread makes while running `f`.
fn allocations_during(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    COUNTED.with(|c| c.set(true));
    f();
    COUNTED.with(|c| c.set(false));
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

/// x² − 2 = 0 and x·y − 1 = 0, a small system for the Newton loop.
struct Small;

impl NonlinearSystem for Small {
    fn dim(&self) -> usize {
        2
    }
    fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
        r[0] = x[0] * x[0] - 2.0;
        r[1] = x[0] * x[1] - 1.0;
        Ok(())
    }
    fn residual_and_jacobian(
        &mut self,
        x: &DVector<f64>,
        r: &mut DVector<f64>,
        j: &mut DMatrix<f64>,
    ) -> Result<(), SolveError> {
        self.residual(x, r)?;
        j[(0, 0)] = 2.0 * x[0];
        j[(0, 1)] = 0.0;
        j[(1, 0)] = x[1];
        j[(1, 1)] = x[0];
        Ok(())
    }
    fn row_weights(&self, w: &mut DVector<f64>) {
        w.fill(1.0);
    }
}

#[test]
fn leg_integration_and_the_newton_loop_do_not_allocate() {
    let robot = common::reference_tdcr();
    let model = LegModel::new(&robot.leg, Vector3::new(0.0, 0.0, -9.81));
    let mut tensions = [0.0; MAX_TENDONS];
    tensions[0] = 3.0;
    let start = LegStart {
        base: Frame::identity(),
        u0: Vector3::new(0.1, 6.0, 0.0),
        v0: Vector3::new(0.0, 0.0, 0.9999),
        tensions,
    };
    let mut scratch = LegScratch::new();
    let mut end = LegEnd::zeros();
    let mut sens = LegSensitivities::new(8);
    let mut shape = LegShape::new(&model);
    let n = allocations_during(|| {
        for _ in 0..3 {
            integrate_leg(&model, &start, &mut scratch, &mut end, None).unwrap();
            integrate_leg_with_sensitivities(
                &model,
                &start,
                &mut scratch,
                &mut end,
                &mut sens,
                None,
            )
            .unwrap();
            integrate_leg(&model, &start, &mut scratch, &mut end, Some(&mut shape)).unwrap();
        }
    });
    assert_eq!(n, 0, "leg integration allocated {n} times");
    assert_eq!(shape.positions.len(), model.n_disks + 1);

    let settings = NewtonSettings::default();
    let mut sc = NewtonScratch::new(2, settings.max_iterations);
    let mut x = DVector::from_vec(vec![3.0, 3.0]);
    let n = allocations_during(|| {
        newton::solve(&mut Small, &mut x, &settings, &mut sc).unwrap();
    });
    assert_eq!(n, 0, "the Newton loop allocated {n} times");
    assert!((x[0] - 2f64.sqrt()).abs() < 1e-10);
}

#[test]
fn the_measures_of_a_configuration_do_not_allocate() {
    for name in ["lilge2022.ron", "lilge2022_redundant.ron"] {
        let design = Tdpcr::from_ron_file(common::design_path(name)).unwrap();
        let mut solver = Solver::new(&design).unwrap();
        let zero = Wrench::default();
        let nq = solver.model().n_actuators();
        let state = solver
            .solve_fk(&vec![0.001; nq], &zero, None)
            .unwrap()
            .state;
        let settings = AnalysisSettings::default();
        // The first call sizes this thread's analysis buffers.
        let first = solver.condition(&state, &zero, &settings).unwrap();
        let mut again = None;
        let n = allocations_during(|| {
            again = Some(solver.condition(&state, &zero, &settings).unwrap());
        });
        assert_eq!(n, 0, "{name}: Solver::condition allocated {n} times");
        assert_eq!(again, Some(first), "{name}: the same measures again");
    }
}
