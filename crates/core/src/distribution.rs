//! Piecewise-constant 1D and 2D distributions, used to importance-sample
//! environment maps (pbrt-v4 §A.5).

/// A piecewise-constant density on `[0, 1)` with `n` equal bins.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f64>,
    cdf: Vec<f64>,
    integral: f64,
}

impl Distribution1D {
    /// Builds the distribution of the non-negative values `func`. If all are
    /// zero the distribution is uniform (so sampling stays defined).
    pub fn new(func: &[f64]) -> Self {
        assert!(!func.is_empty());
        let n = func.len();
        let func: Vec<f64> = func
            .iter()
            .map(|&f| if f.is_finite() && f > 0.0 { f } else { 0.0 })
            .collect();
        let mut cdf = vec![0.0; n + 1];
        for i in 0..n {
            cdf[i + 1] = cdf[i] + func[i] / n as f64;
        }
        let integral = cdf[n];
        if integral > 0.0 {
            for c in cdf.iter_mut() {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n as f64;
            }
        }
        cdf[n] = 1.0;
        Self {
            func,
            cdf,
            integral,
        }
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always false (a distribution has at least one bin).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Integral of the (unnormalized) function over `[0, 1)`.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Samples a point in `[0, 1)`: returns `(x, pdf(x), bin)`.
    pub fn sample(&self, u: f64) -> (f64, f64, usize) {
        let n = self.func.len();
        // Largest index i with cdf[i] <= u.
        let i = match self
            .cdf
            .binary_search_by(|c| c.partial_cmp(&u).unwrap_or(std::cmp::Ordering::Less))
        {
            Ok(i) => i,
            Err(i) => i - 1,
        }
        .min(n - 1);
        // Skip zero-width bins that binary search may land on.
        let mut i = i;
        while i + 1 < n && self.cdf[i + 1] <= u {
            i += 1;
        }
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            (u - self.cdf[i]) / width
        } else {
            0.5
        };
        let x = ((i as f64 + du.clamp(0.0, 1.0)) / n as f64).min(1.0 - f64::EPSILON);
        (x, self.pdf_bin(i), i)
    }

    /// Density of bin `i`.
    pub fn pdf_bin(&self, i: usize) -> f64 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    /// The normalized CDF: `len() + 1` values from 0 to 1 (the GPU
    /// mirrors [`Distribution1D::sample`] from it).
    pub fn cdf(&self) -> &[f64] {
        &self.cdf
    }

    /// Density at `x` in `[0, 1)`.
    pub fn pdf(&self, x: f64) -> f64 {
        let n = self.func.len();
        let i = ((x * n as f64) as usize).min(n - 1);
        self.pdf_bin(i)
    }
}

/// A piecewise-constant density on `[0, 1)^2` over a `nu x nv` grid,
/// sampled as a marginal in `v` and conditionals in `u`.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// `func[v * nu + u]`, row-major with `nv` rows of `nu` values.
    pub fn new(func: &[f64], nu: usize, nv: usize) -> Self {
        assert_eq!(func.len(), nu * nv);
        let conditional: Vec<Distribution1D> = (0..nv)
            .map(|v| Distribution1D::new(&func[v * nu..(v + 1) * nu]))
            .collect();
        let marg: Vec<f64> = conditional.iter().map(|c| c.integral()).collect();
        Self {
            marginal: Distribution1D::new(&marg),
            conditional,
        }
    }

    /// The marginal density over rows (`v`).
    pub fn marginal(&self) -> &Distribution1D {
        &self.marginal
    }

    /// The conditional density over `u` in each row.
    pub fn conditionals(&self) -> &[Distribution1D] {
        &self.conditional
    }

    /// Samples `(u, v)` and returns it with its density.
    pub fn sample(&self, u: [f64; 2]) -> ([f64; 2], f64) {
        let (v, pdf_v, iv) = self.marginal.sample(u[1]);
        let (x, pdf_u, _) = self.conditional[iv].sample(u[0]);
        ([x, v], pdf_u * pdf_v)
    }

    /// Density at `(u, v)`.
    pub fn pdf(&self, p: [f64; 2]) -> f64 {
        let nv = self.conditional.len();
        let iv = ((p[1] * nv as f64) as usize).min(nv - 1);
        self.marginal.pdf_bin(iv) * self.conditional[iv].pdf(p[0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pcg32;

    #[test]
    fn one_d_histogram_matches_pdf() {
        let f = [0.0, 1.0, 3.0, 0.0, 4.0];
        let d = Distribution1D::new(&f);
        let mut rng = Pcg32::new(1, 1);
        let mut hist = [0usize; 5];
        let n = 100_000;
        for _ in 0..n {
            let (x, pdf, i) = d.sample(rng.next_f64());
            assert_eq!((x * 5.0) as usize, i);
            assert!(pdf > 0.0 && (pdf - d.pdf(x)).abs() < 1e-12);
            hist[i] += 1;
        }
        assert_eq!(hist[0] + hist[3], 0);
        for (i, &h) in hist.iter().enumerate() {
            let expect = f[i] / 8.0 * n as f64;
            assert!((h as f64 - expect).abs() < 5.0 * expect.sqrt() + 1.0);
        }
    }

    #[test]
    fn two_d_pdf_integrates_to_one() {
        let (nu, nv) = (8, 4);
        let f: Vec<f64> = (0..nu * nv).map(|i| ((i * 7) % 5) as f64).collect();
        let d = Distribution2D::new(&f, nu, nv);
        let mut s = 0.0;
        for v in 0..nv {
            for u in 0..nu {
                s += d.pdf([(u as f64 + 0.5) / nu as f64, (v as f64 + 0.5) / nv as f64]);
            }
        }
        assert!((s / (nu * nv) as f64 - 1.0).abs() < 1e-12);
        let mut rng = Pcg32::new(2, 2);
        for _ in 0..1000 {
            let (p, pdf) = d.sample(rng.next_2d());
            assert!((pdf - d.pdf(p)).abs() < 1e-9 * pdf.max(1.0));
        }
    }
}
