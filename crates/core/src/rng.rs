//! Deterministic random numbers.
//!
//! Isolux renders bit-identical images for a fixed seed whatever the thread
//! count: every pixel owns a generator seeded from `(scene seed, pixel index)`
//! through a hash, so no state is shared between tasks. The generator is
//! PCG32 (O'Neill 2014, XSH-RR variant), small and statistically sound.

/// PCG32 random number generator (64-bit state, 32-bit output).
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULT: u64 = 6364136223846793005;

impl Pcg32 {
    /// A generator for `seed` on stream `stream` (distinct streams are
    /// independent sequences).
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut r = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        r.next_u32();
        r.state = r.state.wrapping_add(seed);
        r.next_u32();
        r
    }

    /// Next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform double in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        ((hi | lo) as f64) * (1.0 / (1u64 << 53) as f64)
    }

    /// Two uniform doubles.
    #[inline]
    pub fn next_2d(&mut self) -> [f64; 2] {
        [self.next_f64(), self.next_f64()]
    }

    /// Uniform integer in `[0, n)` (Lemire's nearly-divisionless method is
    /// overkill here; rejection keeps it exact).
    pub fn next_below(&mut self, n: u32) -> u32 {
        assert!(n > 0);
        let threshold = n.wrapping_neg() % n;
        loop {
            let r = self.next_u32();
            if r >= threshold {
                return r % n;
            }
        }
    }
}

/// A 64-bit mixing hash (SplitMix64 finalizer) to derive seeds.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E3779B97F4A7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_mean_and_range() {
        let mut r = Pcg32::new(42, 7);
        let n = 200_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let x = r.next_f64();
            assert!((0.0..1.0).contains(&x));
            sum += x;
        }
        let mean = sum / n as f64;
        // std of the mean is 0.2887/sqrt(n) = 6.5e-4; 5 sigma.
        assert!((mean - 0.5).abs() < 3.3e-3, "{mean}");
    }

    #[test]
    fn streams_differ_and_repeat() {
        let a: Vec<u32> = (0..8)
            .scan(Pcg32::new(1, 1), |r, _| Some(r.next_u32()))
            .collect();
        let b: Vec<u32> = (0..8)
            .scan(Pcg32::new(1, 2), |r, _| Some(r.next_u32()))
            .collect();
        let c: Vec<u32> = (0..8)
            .scan(Pcg32::new(1, 1), |r, _| Some(r.next_u32()))
            .collect();
        assert_ne!(a, b);
        assert_eq!(a, c);
    }

    #[test]
    fn next_below_is_in_range() {
        let mut r = Pcg32::new(3, 3);
        let mut hist = [0u32; 7];
        for _ in 0..70_000 {
            hist[r.next_below(7) as usize] += 1;
        }
        for h in hist {
            assert!((9_500..10_500).contains(&h), "{hist:?}");
        }
    }
}
