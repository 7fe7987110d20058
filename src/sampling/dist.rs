//! A piecewise-constant 1-D distribution on cells with arbitrary edges
//! (pbrt's `Distribution1D`, generalised to non-uniform cells).

/// Density constant on each cell `[edges[i], edges[i+1])`; the probability
/// of cell i is `cdf[i+1] - cdf[i]`, and `cdf` ends at exactly 1.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseConstant {
    edges: Vec<f64>,
    cdf: Vec<f64>,
    density: Vec<f64>,
    /// Guide table (Devroye's indexed search): entry b is the last cell i
    /// with `cdf[i] <= b / cells`, where the search for u in
    /// `[b, b + 1) / cells` starts; a few steps forward find the cell the
    /// binary search would (one or two on average, and the same cell).
    guide: Vec<u32>,
}

impl PiecewiseConstant {
    /// `mass[i]` is the (unnormalised, non-negative) mass of cell i; `edges`
    /// has one more entry than `mass` and increases strictly. `None` when
    /// the total mass is zero or not finite, or the inputs are inconsistent.
    pub fn new(edges: Vec<f64>, mass: &[f64]) -> Option<Self> {
        if edges.len() != mass.len() + 1 || mass.is_empty() {
            return None;
        }
        if edges
            .windows(2)
            .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
        {
            return None;
        }
        if mass.iter().any(|m| !(m.is_finite() && *m >= 0.0)) {
            return None;
        }
        let total: f64 = mass.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let mut cdf = Vec::with_capacity(edges.len());
        let mut acc = 0.0;
        cdf.push(0.0);
        for m in mass {
            acc += m;
            cdf.push(acc / total);
        }
        // Make the last entry exactly 1 (and keep the sequence monotone).
        let n = mass.len();
        cdf[n] = 1.0;
        for i in (1..n).rev() {
            if cdf[i] > cdf[i + 1] {
                cdf[i] = cdf[i + 1];
            }
        }
        // Densities from the stored cdf itself, so sample and pdf agree exactly.
        let density = (0..n)
            .map(|i| (cdf[i + 1] - cdf[i]) / (edges[i + 1] - edges[i]))
            .collect();
        let guide = (0..n)
            .map(|b| {
                let u = b as f64 / n as f64;
                (cdf.partition_point(|&c| c <= u).saturating_sub(1)).min(n - 1) as u32
            })
            .collect();
        Some(PiecewiseConstant {
            edges,
            cdf,
            density,
            guide,
        })
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.density.len()
    }

    /// Cell edges (one more than cells), increasing.
    pub fn edges(&self) -> &[f64] {
        &self.edges
    }

    /// Cumulative probabilities at the edges, from 0 to exactly 1.
    pub fn cdf(&self) -> &[f64] {
        &self.cdf
    }

    /// Probability of cell i.
    pub fn cell_probability(&self, i: usize) -> f64 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Bytes of table storage (edges, cdf, densities as f64, the guide
    /// table as u32).
    pub fn table_bytes(&self) -> usize {
        8 * (self.edges.len() + self.cdf.len() + self.density.len()) + 4 * self.guide.len()
    }

    /// x in `[edges[0], edges[n])` distributed with this density, for u in [0, 1).
    /// Cells of zero probability are never chosen.
    #[inline]
    pub fn sample(&self, u: f64) -> f64 {
        self.sample_cell(u).1
    }

    /// [`PiecewiseConstant::sample`] with the index of the cell drawn.
    #[inline(always)]
    pub fn sample_cell(&self, u: f64) -> (usize, f64) {
        let n = self.cells();
        let u = if u.is_finite() {
            u.clamp(0.0, 1.0)
        } else {
            0.0
        };
        // Last i with cdf[i] <= u (from the guide table, then forward; the
        // step back only guards the rounding of b / n against u).
        // u * n in [0, n] (n < 2^31): a 32-bit truncation is the floor
        // (fewer instructions than a saturating conversion to usize).
        let b = ((u * n as f64) as i32).max(0) as usize;
        let b = b.min(n - 1);
        let mut i = self.guide[b] as usize;
        while i + 1 < self.cdf.len() && self.cdf[i + 1] <= u {
            i += 1;
        }
        while i > 0 && self.cdf[i] > u {
            i -= 1;
        }
        // Below n, cdf[i] <= u < cdf[i + 1]: cell i has mass. Only u at
        // the end (1) walks back past cells without any.
        if i >= n {
            i = n - 1;
            while self.cdf[i + 1] <= self.cdf[i] && i > 0 {
                i -= 1;
            }
        }
        let p = self.cdf[i + 1] - self.cdf[i];
        let du = if p > 0.0 {
            ((u - self.cdf[i]) / p).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let (a, b) = (self.edges[i], self.edges[i + 1]);
        // Stay inside the half-open cell so pdf finds the same cell.
        let x = a + du * (b - a);
        if x >= b {
            (i, a + (b - a) * (1.0 - f64::EPSILON))
        } else {
            (i, x)
        }
    }

    /// The cell holding x (None outside the support).
    #[inline]
    pub fn cell_of(&self, x: f64) -> Option<usize> {
        let n = self.cells();
        if !(x >= self.edges[0] && x < self.edges[n]) {
            return None;
        }
        Some((self.edges.partition_point(|&e| e <= x) - 1).min(n - 1))
    }

    /// Density of cell i.
    #[inline]
    pub fn cell_density(&self, i: usize) -> f64 {
        self.density[i]
    }

    /// Density at x (zero outside the support).
    #[inline]
    pub fn pdf(&self, x: f64) -> f64 {
        self.cell_of(x).map_or(0.0, |i| self.density[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_stay_in_their_cells_and_pdf_matches() {
        let d =
            PiecewiseConstant::new(vec![0.0, 0.1, 0.5, 0.6, 1.0], &[1.0, 0.0, 2.0, 1.0]).unwrap();
        assert_eq!(d.cdf()[4], 1.0);
        for k in 0..1000 {
            let u = k as f64 / 1000.0;
            let x = d.sample(u);
            assert!((0.0..1.0).contains(&x));
            assert!(!(0.1..0.5).contains(&x), "zero cell sampled at u={u}: {x}");
            assert!(d.pdf(x) > 0.0);
        }
        let total: f64 = (0..4).map(|i| d.cell_probability(i)).sum();
        assert!((total - 1.0).abs() < 1e-15);
        assert!(d.sample(1.0) < 1.0 && d.pdf(d.sample(1.0)) > 0.0);
        assert_eq!(d.pdf(1.0), 0.0);
        assert!(PiecewiseConstant::new(vec![0.0, 1.0], &[0.0]).is_none());
        assert!(PiecewiseConstant::new(vec![0.0, 1.0], &[f64::NAN]).is_none());
    }

    #[test]
    fn the_guide_table_finds_the_binary_search_cell() {
        // A peaky distribution with plateaus (zero cells) and tiny cells.
        let n = 361;
        let edges: Vec<f64> = (0..=n).map(|k| (k as f64 / n as f64).powi(4)).collect();
        let mass: Vec<f64> = (0..n)
            .map(|k| match k % 17 {
                0 | 5 => 0.0,
                _ => (-(k as f64) / 9.0).exp() + 1e-13,
            })
            .collect();
        let d = PiecewiseConstant::new(edges, &mass).unwrap();
        let reference = |u: f64| {
            let mut i = d
                .cdf
                .partition_point(|&c| c <= u)
                .saturating_sub(1)
                .min(n - 1);
            while d.cdf[i + 1] <= d.cdf[i] && i > 0 {
                i -= 1;
            }
            i
        };
        let mut us: Vec<f64> = (0..200_000).map(|k| k as f64 / 200_000.0).collect();
        us.extend(
            d.cdf
                .iter()
                .flat_map(|&c| [c, c - 1e-17, c + 1e-16, c * (1.0 - 1e-16)]),
        );
        us.extend([0.0, 1.0, 1.0 - 1e-17, -1.0, 2.0]);
        for u in us {
            let uc = u.clamp(0.0, 1.0);
            assert_eq!(d.sample_cell(u).0, reference(uc), "u = {u}");
        }
    }

    #[test]
    fn u_at_one_draws_the_last_cell_with_mass() {
        // Trailing empty cells: u = 1 (and above, clamped) walks back past
        // them; just below 1 the search lands there directly.
        let d =
            PiecewiseConstant::new(vec![0.0, 0.1, 0.5, 0.7, 1.0], &[1.0, 2.0, 0.0, 0.0]).unwrap();
        for u in [1.0, 2.0, 1.0 - 1e-12] {
            assert_eq!(d.sample_cell(u).0, 1, "u = {u}");
        }
        assert_eq!(d.sample_cell(0.0).0, 0);
    }
}
