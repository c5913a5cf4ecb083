//! The one seeded pseudo-random generator of tdpcr and its users (the actuation sampler,
//! the design optimizer's CMA-ES, the tests): SplitMix64 (Steele, Lea & Flood 2014). The
//! same seed gives the same stream on every platform; the streams are part of the
//! reproducibility of the seeded sets (`sampling`) and of the optimizer's logs, so they
//! must never change (pinned by a test).

/// SplitMix64: 64 random bits per call from a 64-bit counter.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// The stream of `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// The next 53 random bits as k / 2⁵³ in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi) (computed as lo + (hi − lo) · k / 2⁵³).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stream_is_splitmix64_and_never_changes() {
        // SplitMix64 from state 0 (the published reference values).
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        assert_eq!(r.next_u64(), 0x06C4_5D18_8009_454F);
        let mut r = SplitMix64::new(42);
        let a = r.unit();
        assert!((0.0..1.0).contains(&a));
        assert_eq!(SplitMix64::new(42).unit().to_bits(), a.to_bits());
    }
}
