//! A counter-based random stream (SplitMix64 finaliser of `seed + (i + 1) · γ`), so the i-th
//! number of a seed is known without drawing the ones before it, and numpy can reproduce the
//! stream with vectorised `uint64` arithmetic.

/// The golden-ratio increment of SplitMix64.
pub const GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's output function.
#[inline]
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The `index`-th 64-bit word of the stream of `seed`.
#[inline]
pub fn word(seed: u64, index: u64) -> u64 {
    mix(seed.wrapping_add(index.wrapping_add(1).wrapping_mul(GAMMA)))
}

/// A position in the stream of one seed; every draw advances `counter`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stream {
    /// The seed.
    pub seed: u64,
    /// Words drawn so far.
    pub counter: u64,
}

impl Stream {
    /// The stream of `seed` from its start.
    pub fn new(seed: u64) -> Self {
        Self { seed, counter: 0 }
    }

    /// A uniform number in [0, 1) (53 bits; one word).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        let w = word(self.seed, self.counter);
        self.counter += 1;
        (w >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A standard normal number by Box–Muller, `sqrt(−2 ln(1 − u₁)) cos(2π u₂)` (two words).
    #[inline]
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform();
        let u2 = self.uniform();
        (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_reference_values() {
        // SplitMix64 seeded with 0: the published first outputs.
        assert_eq!(word(0, 0), 0xe220_a839_7b1d_cdaf);
        assert_eq!(word(0, 1), 0x6e78_9e6a_a1b9_65f4);
    }

    #[test]
    fn normals_have_unit_variance() {
        let mut s = Stream::new(7);
        let n = 20_000;
        let x: Vec<f64> = (0..n).map(|_| s.normal()).collect();
        let mean = x.iter().sum::<f64>() / n as f64;
        let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
        assert_eq!(s.counter, 2 * n as u64);
    }
}
