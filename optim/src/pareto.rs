//! Pareto dominance and non-dominated sorting, all objectives **maximized**.

/// `a` Pareto-dominates `b`: at least as good in every objective and strictly better in
/// one (maximization). Slices of different lengths never dominate each other.
pub fn dominates(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| x >= y)
        && a.iter().zip(b).any(|(x, y)| x > y)
}

/// Non-dominated sorting (Deb et al. 2002): the indices of `points` in successive
/// fronts. Front 0 is the Pareto front (no point dominates its members); front k holds the
/// points dominated only by points of fronts < k. Within a front, indices ascend; equal
/// points share a front.
pub fn non_dominated_sort<P: AsRef<[f64]>>(points: &[P]) -> Vec<Vec<usize>> {
    let n = points.len();
    let mut dominated_by_count = vec![0usize; n];
    let mut dominates_list: Vec<Vec<usize>> = vec![Vec::new(); n];
    for i in 0..n {
        for j in (i + 1)..n {
            let (a, b) = (points[i].as_ref(), points[j].as_ref());
            if dominates(a, b) {
                dominates_list[i].push(j);
                dominated_by_count[j] += 1;
            } else if dominates(b, a) {
                dominates_list[j].push(i);
                dominated_by_count[i] += 1;
            }
        }
    }
    let mut fronts = Vec::new();
    let mut current: Vec<usize> = (0..n).filter(|&i| dominated_by_count[i] == 0).collect();
    while !current.is_empty() {
        let mut next = Vec::new();
        for &i in &current {
            for &j in &dominates_list[i] {
                dominated_by_count[j] -= 1;
                if dominated_by_count[j] == 0 {
                    next.push(j);
                }
            }
        }
        next.sort_unstable();
        fronts.push(std::mem::replace(&mut current, next));
    }
    fronts
}

/// The indices of the Pareto front of `points` (front 0 of [`non_dominated_sort`]).
pub fn pareto_front<P: AsRef<[f64]>>(points: &[P]) -> Vec<usize> {
    non_dominated_sort(points)
        .into_iter()
        .next()
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dominance_needs_one_strict_improvement() {
        assert!(dominates(&[2.0, 1.0, 1.0], &[1.0, 1.0, 1.0]));
        assert!(!dominates(&[1.0, 1.0, 1.0], &[1.0, 1.0, 1.0]));
        assert!(!dominates(&[2.0, 0.0, 1.0], &[1.0, 1.0, 1.0]));
        assert!(!dominates(&[2.0, 1.0], &[1.0, 1.0, 1.0]));
    }

    #[test]
    fn fronts_of_a_small_set() {
        let pts = [
            [1.0, 5.0, 0.0], // 0: front 0
            [5.0, 1.0, 0.0], // 1: front 0
            [3.0, 3.0, 0.0], // 2: front 0
            [2.0, 2.0, 0.0], // 3: dominated by 2 -> front 1
            [1.0, 1.0, 0.0], // 4: dominated by 3 -> front 2
            [3.0, 3.0, 0.0], // 5: equal to 2 -> front 0
            [0.5, 4.0, 0.0], // 6: dominated by 0 -> front 1
        ];
        let fronts = non_dominated_sort(&pts);
        assert_eq!(fronts, vec![vec![0, 1, 2, 5], vec![3, 6], vec![4]]);
        assert_eq!(pareto_front(&pts), vec![0, 1, 2, 5]);
        // Every point in exactly one front; no member of a front dominated by another.
        let mut all: Vec<usize> = fronts.concat();
        all.sort_unstable();
        assert_eq!(all, (0..pts.len()).collect::<Vec<_>>());
        for f in &fronts {
            for &a in f {
                assert!(f.iter().all(|&b| !dominates(&pts[b], &pts[a])));
            }
        }
    }

    #[test]
    fn brute_force_agrees_on_seeded_random_points() {
        let mut rng = crate::rng::Rng::new(5);
        let pts: Vec<Vec<f64>> = (0..200)
            .map(|_| (0..3).map(|_| (rng.uniform() * 10.0).floor()).collect())
            .collect();
        let front = pareto_front(&pts);
        let brute: Vec<usize> = (0..pts.len())
            .filter(|&i| !pts.iter().any(|q| dominates(q, &pts[i])))
            .collect();
        assert_eq!(front, brute);
        assert!(pareto_front::<Vec<f64>>(&[]).is_empty());
    }
}
