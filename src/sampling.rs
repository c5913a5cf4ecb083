//! Deterministic sampling of actuation vectors (benchmarks, Monte Carlo studies).

use crate::model::Model;

/// `count` actuation vectors from a fixed pseudo-random sequence (SplitMix64 of `seed`):
/// each bending value uniform in ±`tendon_displacement`; the translations a common offset
/// uniform in ±0.8 `base_translation` plus a per-leg offset uniform in ±0.2
/// `base_translation` (independent translations of ±100 mm on 145 mm legs mostly ask
/// for configurations without an equilibrium).
pub fn seeded_actuations(model: &Model, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut state = seed;
    let mut uniform = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let (bend, trans) = (
        model.limits.tendon_displacement,
        model.limits.base_translation,
    );
    (0..count)
        .map(|_| {
            let common = 0.8 * trans * uniform();
            (0..model.n_actuators())
                .map(|k| {
                    if k % (model.pairs + 1) == model.pairs {
                        common + 0.2 * trans * uniform()
                    } else {
                        bend * uniform()
                    }
                })
                .collect()
        })
        .collect()
}
