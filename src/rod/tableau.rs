//! Butcher tableaus of the fixed-step explicit Runge–Kutta methods of the leg
//! integration ([`Integrator`]).
//!
//! Why Butcher's fifth-order method is the default: at the tip of a strongly bent leg of
//! the 9-DoF reference design (9 of the 10 mm tendon displacements, bases 5 cm apart),
//! against 4096 RK4 steps, the tip position and rotation × L errors were (2026-11-26)
//!
//! | method, steps | right-hand sides | position | rotation × L |
//! |---|---|---|---|
//! | RK4, 26 (the default before) | 104 | 1.2e-7 m | 1.2e-6 m |
//! | RK4, 13 | 52 | 2.6e-6 m | 1.9e-5 m |
//! | Butcher RK5, 13 | 78 | 2.4e-8 m | 2.0e-7 m |
//! | Butcher RK5, 10 | 60 | 8.5e-8 m | 7.3e-7 m |
//! | Kutta–Nyström RK5, 13 | 78 | 2.1e-7 m | 9.6e-7 m |
//! | Dormand–Prince RK5 (its 5th-order weights), 13 | 78 (72 with FSAL) | 6.8e-8 m | 4.4e-7 m |
//! | Butcher RK6 (7 stages), 8 | 56 | 5.7e-7 m | 3.0e-6 m |
//!
//! (the other legs and the 6-DoF design alike). The default takes 10 steps (60
//! right-hand sides): the disks are not step boundaries, their frames come from partial
//! steps of the same method (`rod::integrate`). At the ten configurations of
//! `tests/discretization.rs` the platform is then within 2.4e-7 m (position) and 2.4e-7 m
//! (rotation × L) of 16× the steps, against 1.7e-7 m and 5.6e-7 m for RK4 at 26 steps.

use crate::design::Integrator;

/// Most stages of a method.
pub const MAX_STAGES: usize = 6;

/// An explicit Runge–Kutta method: stage i's input is y + h Σ_{j<i} a\[i\]\[j\] k_j, the
/// step is y + h Σ_i b\[i\] k_i. Built by [`Tableau::new`], which also lists each stage
/// input's nonzero terms (so the kernel loops over no zeros and tests no coefficient).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tableau {
    /// Number of stages s (≤ [`MAX_STAGES`]).
    pub(crate) stages: usize,
    /// Stage coefficients (strictly lower triangular).
    pub(crate) a: [[f64; MAX_STAGES]; MAX_STAGES],
    /// Weights.
    pub(crate) b: [f64; MAX_STAGES],
    /// The nonzero terms of each stage input, j ascending.
    pub(crate) inputs: [Terms; MAX_STAGES],
    /// The nonzero terms of each stage input i but the previous stage's (j < i − 1): what
    /// the tangents' stage input adds, in this order, after the previous stage's term.
    pub(crate) earlier: [Terms; MAX_STAGES],
}

/// The nonzero terms (j, c_j) of a sum Σ_j c_j k_j, j ascending.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Terms {
    /// Number of terms.
    pub n: usize,
    /// Stage index j of each term.
    pub stage: [usize; MAX_STAGES],
    /// Coefficient c_j of each term.
    pub coefficient: [f64; MAX_STAGES],
}

impl Terms {
    /// The nonzero entries of `row`, j ascending.
    const fn of(row: &[f64; MAX_STAGES]) -> Self {
        let mut t = Self {
            n: 0,
            stage: [0; MAX_STAGES],
            coefficient: [0.0; MAX_STAGES],
        };
        let mut j = 0;
        while j < MAX_STAGES {
            if row[j] != 0.0 {
                t.stage[t.n] = j;
                t.coefficient[t.n] = row[j];
                t.n += 1;
            }
            j += 1;
        }
        t
    }

    /// The terms, (j, c_j).
    #[cfg(test)]
    fn iter(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.stage[..self.n]
            .iter()
            .copied()
            .zip(self.coefficient[..self.n].iter().copied())
    }
}

impl Tableau {
    /// The method with `stages` stages, coefficients `a` (strictly lower triangular) and
    /// weights `b`.
    ///
    /// # Panics
    /// If `stages` is not in 1..=[`MAX_STAGES`], or `a` has an entry on or above the
    /// diagonal or beyond the stages, or `b` beyond them (at compile time for a `const`).
    pub const fn new(
        stages: usize,
        a: [[f64; MAX_STAGES]; MAX_STAGES],
        b: [f64; MAX_STAGES],
    ) -> Self {
        assert!(
            stages >= 1 && stages <= MAX_STAGES,
            "1 to MAX_STAGES stages"
        );
        let mut i = 0;
        while i < MAX_STAGES {
            let mut j = 0;
            while j < MAX_STAGES {
                assert!(
                    a[i][j] == 0.0 || (j < i && i < stages),
                    "a must be strictly lower triangular within the stages"
                );
                j += 1;
            }
            assert!(b[i] == 0.0 || i < stages, "no weight beyond the stages");
            i += 1;
        }
        let none = Terms::of(&[0.0; MAX_STAGES]);
        let (mut inputs, mut earlier) = ([none; MAX_STAGES], [none; MAX_STAGES]);
        let mut i = 0;
        while i < MAX_STAGES {
            inputs[i] = Terms::of(&a[i]);
            let mut row = a[i];
            if i > 0 {
                row[i - 1] = 0.0;
            }
            earlier[i] = Terms::of(&row);
            i += 1;
        }
        Self {
            stages,
            a,
            b,
            inputs,
            earlier,
        }
    }
}

/// The classical fourth-order method.
pub const RK4: Tableau = Tableau::new(
    4,
    [
        [0.0; 6],
        [0.5, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.5, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
        [0.0; 6],
        [0.0; 6],
    ],
    [1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0, 0.0, 0.0],
);

/// Butcher's fifth-order method with six stages (J. C. Butcher, Numerical Methods for
/// Ordinary Differential Equations, 2008, eq. 236a; c = 0, 1/4, 1/4, 1/2, 3/4, 1).
pub const RK5: Tableau = Tableau::new(
    6,
    [
        [0.0; 6],
        [0.25, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.125, 0.125, 0.0, 0.0, 0.0, 0.0],
        [0.0, -0.5, 1.0, 0.0, 0.0, 0.0],
        [3.0 / 16.0, 0.0, 0.0, 9.0 / 16.0, 0.0, 0.0],
        [
            -3.0 / 7.0,
            2.0 / 7.0,
            12.0 / 7.0,
            -12.0 / 7.0,
            8.0 / 7.0,
            0.0,
        ],
    ],
    [
        7.0 / 90.0,
        0.0,
        32.0 / 90.0,
        12.0 / 90.0,
        32.0 / 90.0,
        7.0 / 90.0,
    ],
);

/// The tableau of `method`.
pub fn tableau(method: Integrator) -> &'static Tableau {
    match method {
        Integrator::Rk4 => &RK4,
        Integrator::Rk5 => &RK5,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 17 order conditions up to order 5 (one per rooted tree), as
    /// (order, Σ over the tree's elementary weight, 1 / tree factorial).
    fn order_conditions(t: &Tableau) -> Vec<(usize, f64, f64)> {
        let s = t.stages;
        let b = &t.b[..s];
        let a = |i: usize, j: usize| t.a[i][j];
        let mul = |x: &[f64]| -> Vec<f64> {
            (0..s)
                .map(|i| (0..s).map(|j| a(i, j) * x[j]).sum())
                .collect()
        };
        let dot = |x: &[f64]| -> f64 { b.iter().zip(x).map(|(b, x)| b * x).sum() };
        let pw = |x: &[f64], k: i32| -> Vec<f64> { x.iter().map(|v| v.powi(k)).collect() };
        let hd =
            |x: &[f64], y: &[f64]| -> Vec<f64> { x.iter().zip(y).map(|(x, y)| x * y).collect() };
        let one = vec![1.0; s];
        let c = mul(&one);
        let ac = mul(&c);
        let ac2 = mul(&pw(&c, 2));
        let aac = mul(&ac);
        vec![
            (1, dot(&one), 1.0),
            (2, dot(&c), 1.0 / 2.0),
            (3, dot(&pw(&c, 2)), 1.0 / 3.0),
            (3, dot(&ac), 1.0 / 6.0),
            (4, dot(&pw(&c, 3)), 1.0 / 4.0),
            (4, dot(&hd(&c, &ac)), 1.0 / 8.0),
            (4, dot(&ac2), 1.0 / 12.0),
            (4, dot(&aac), 1.0 / 24.0),
            (5, dot(&pw(&c, 4)), 1.0 / 5.0),
            (5, dot(&hd(&pw(&c, 2), &ac)), 1.0 / 10.0),
            (5, dot(&hd(&c, &ac2)), 1.0 / 15.0),
            (5, dot(&hd(&c, &aac)), 1.0 / 30.0),
            (5, dot(&pw(&ac, 2)), 1.0 / 20.0),
            (5, dot(&mul(&pw(&c, 3))), 1.0 / 20.0),
            (5, dot(&mul(&hd(&c, &ac))), 1.0 / 40.0),
            (5, dot(&mul(&ac2)), 1.0 / 60.0),
            (5, dot(&mul(&aac)), 1.0 / 120.0),
        ]
    }

    #[test]
    fn each_method_meets_the_order_conditions_of_its_order_and_not_the_next() {
        for (t, order) in [(&RK4, 4), (&RK5, 5)] {
            let conditions = order_conditions(t);
            for (k, &(o, value, expected)) in conditions.iter().enumerate() {
                if o <= order {
                    assert!(
                        (value - expected).abs() < 1e-14,
                        "{} stages: condition {k} (order {o}) is {value}, expected {expected}",
                        t.stages
                    );
                }
            }
            if order < 5 {
                assert!(
                    conditions
                        .iter()
                        .any(|&(o, v, e)| o == order + 1 && (v - e).abs() > 1e-6),
                    "{} stages: of higher order than {order}",
                    t.stages
                );
            }
        }
    }

    #[test]
    fn a_stage_input_lists_the_earlier_stages_it_reads_apart_from_the_previous_one() {
        // Stage 5's input reads k_0 .. k_4: k_4 first, then the earlier four in order.
        let earlier: Vec<_> = RK5.earlier[5].iter().map(|(j, _)| j).collect();
        assert_eq!(earlier, [0, 1, 2, 3]);
        assert_eq!(RK5.inputs[5].n, 5);
        assert_eq!(RK4.earlier.iter().map(|t| t.n).sum::<usize>(), 0);
    }
}
