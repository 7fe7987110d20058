//! A piecewise-constant 2-D distribution (pbrt's `PiecewiseConstant2D`, on
//! cells with arbitrary edges): a marginal over rows of x, and per row a
//! conditional over y, each a [`PiecewiseConstant`].

use super::PiecewiseConstant;

/// Density constant on each cell `[x_i, x_i+1) x [y_j, y_j+1)`.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseConstant2D {
    marginal: PiecewiseConstant,
    /// One per row; `None` for a row without mass (never drawn).
    conditional: Vec<Option<PiecewiseConstant>>,
}

impl PiecewiseConstant2D {
    /// `mass[i * ny + j]` is the (unnormalised, non-negative) mass of cell
    /// (i, j), `ny = y_edges.len() - 1`. `None` when the total is zero or
    /// not finite, or the sizes disagree.
    pub fn new(x_edges: Vec<f64>, y_edges: Vec<f64>, mass: &[f64]) -> Option<Self> {
        let nx = x_edges.len().checked_sub(1)?;
        let ny = y_edges.len().checked_sub(1)?;
        if nx == 0 || ny == 0 || mass.len() != nx * ny {
            return None;
        }
        let rows: Vec<f64> = mass.chunks(ny).map(|r| r.iter().sum()).collect();
        let marginal = PiecewiseConstant::new(x_edges, &rows)?;
        let conditional = mass
            .chunks(ny)
            .map(|r| PiecewiseConstant::new(y_edges.clone(), r))
            .collect();
        Some(PiecewiseConstant2D {
            marginal,
            conditional,
        })
    }

    fn row(&self, x: f64) -> Option<usize> {
        let e = self.marginal.edges();
        let n = e.len() - 1;
        if !(x >= e[0] && x < e[n]) {
            return None;
        }
        Some((e.partition_point(|&v| v <= x) - 1).min(n - 1))
    }

    /// (x, y) with this density for `u` in [0, 1)^2; cells of zero
    /// probability are never drawn.
    pub fn sample(&self, u: [f64; 2]) -> (f64, f64) {
        let x = self.marginal.sample(u[0]);
        let c = self
            .row(x)
            .and_then(|i| self.conditional[i].as_ref())
            .expect("the marginal draws rows with mass only");
        (x, c.sample(u[1]))
    }

    /// Density at (x, y) (zero outside the support).
    pub fn pdf(&self, x: f64, y: f64) -> f64 {
        match self.row(x).and_then(|i| self.conditional[i].as_ref()) {
            Some(c) => self.marginal.pdf(x) * c.pdf(y),
            None => 0.0,
        }
    }

    /// Bytes of table storage.
    pub fn table_bytes(&self) -> usize {
        self.marginal.table_bytes()
            + self
                .conditional
                .iter()
                .flatten()
                .map(PiecewiseConstant::table_bytes)
                .sum::<usize>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_frequencies_match_masses_and_pdf_integrates_to_one() {
        let xe = vec![0.0, 0.2, 0.7, 1.0];
        let ye = vec![0.0, 1.0, 3.0];
        let mass = [1.0, 2.0, 0.0, 0.0, 3.0, 4.0];
        let d = PiecewiseConstant2D::new(xe.clone(), ye.clone(), &mass).unwrap();
        let mut integral = 0.0;
        for i in 0..3 {
            for j in 0..2 {
                let (x, y) = (0.5 * (xe[i] + xe[i + 1]), 0.5 * (ye[j] + ye[j + 1]));
                integral += d.pdf(x, y) * (xe[i + 1] - xe[i]) * (ye[j + 1] - ye[j]);
            }
        }
        assert!((integral - 1.0).abs() < 1e-12, "{integral}");
        let n = 200;
        let mut counts = [0usize; 6];
        for a in 0..n {
            for b in 0..n {
                let (x, y) = d.sample([(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64]);
                assert!(d.pdf(x, y) > 0.0);
                let i = xe.partition_point(|&e| e <= x) - 1;
                let j = ye.partition_point(|&e| e <= y) - 1;
                counts[i * 2 + j] += 1;
            }
        }
        for (k, &c) in counts.iter().enumerate() {
            let expected = mass[k] / 10.0 * (n * n) as f64;
            assert!((c as f64 - expected).abs() <= 0.01 * (n * n) as f64, "cell {k}: {c} vs {expected}");
        }
        assert!(PiecewiseConstant2D::new(xe, ye, &[0.0; 6]).is_none());
    }
}
