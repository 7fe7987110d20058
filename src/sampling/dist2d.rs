//! A piecewise-constant 2-D distribution: cells with arbitrary edges in x
//! (a [`PiecewiseConstant`] marginal) times uniform cells in y on
//! [0, y_max), one conditional distribution per x cell (pbrt's
//! `Distribution2D` with non-uniform x cells).

use super::PiecewiseConstant;

/// Density constant on each cell; sampling and [`PiecewiseConstant2D::pdf`]
/// use the same stored cumulative sums, so the density is exactly what is
/// drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseConstant2D {
    marginal: PiecewiseConstant,
    ny: usize,
    y_max: f64,
    /// ny + 1 cumulative probabilities per x cell, from 0 to exactly 1.
    cdf: Vec<f64>,
}

impl PiecewiseConstant2D {
    /// `mass[i * ny + j]` is the (unnormalised, non-negative) mass of cell
    /// (i, j): x in `[x_edges[i], x_edges[i+1])`, y in `[j, j+1) y_max / ny`.
    /// `None` when the total is zero or not finite, or inputs are inconsistent.
    pub fn new(x_edges: Vec<f64>, ny: usize, y_max: f64, mass: &[f64]) -> Option<Self> {
        let nx = x_edges.len().checked_sub(1)?;
        if ny == 0 || nx == 0 || mass.len() != nx * ny || !(y_max > 0.0 && y_max.is_finite()) {
            return None;
        }
        if mass.iter().any(|m| !(m.is_finite() && *m >= 0.0)) {
            return None;
        }
        let rows: Vec<f64> = mass.chunks(ny).map(|r| r.iter().sum()).collect();
        let marginal = PiecewiseConstant::new(x_edges, &rows)?;
        let mut cdf = Vec::with_capacity(nx * (ny + 1));
        for (row, &total) in mass.chunks(ny).zip(&rows) {
            let start = cdf.len();
            cdf.push(0.0);
            let mut acc = 0.0;
            for (j, m) in row.iter().enumerate() {
                acc += m;
                // A row without mass is never drawn; keep it uniform.
                cdf.push(if total > 0.0 {
                    acc / total
                } else {
                    (j + 1) as f64 / ny as f64
                });
            }
            cdf[start + ny] = 1.0;
            for k in (1..ny).rev() {
                if cdf[start + k] > cdf[start + k + 1] {
                    cdf[start + k] = cdf[start + k + 1];
                }
            }
        }
        Some(PiecewiseConstant2D {
            marginal,
            ny,
            y_max,
            cdf,
        })
    }

    /// The marginal distribution in x.
    pub fn marginal(&self) -> &PiecewiseConstant {
        &self.marginal
    }

    /// Cells in y per x cell.
    pub fn y_cells(&self) -> usize {
        self.ny
    }

    /// The upper end of y's range.
    pub fn y_max(&self) -> f64 {
        self.y_max
    }

    /// Probability of y cell j given x cell i.
    #[inline]
    pub fn conditional_probability(&self, i: usize, j: usize) -> f64 {
        let r = i * (self.ny + 1);
        self.cdf[r + j + 1] - self.cdf[r + j]
    }

    /// Bytes of table storage (f64).
    pub fn table_bytes(&self) -> usize {
        self.marginal.table_bytes() + 8 * self.cdf.len()
    }

    /// (x, y) for u in [0, 1)^2: u[0] picks x from the marginal, u[1] y
    /// from x's row. Cells of zero probability are never chosen.
    #[inline]
    pub fn sample(&self, u: [f64; 2]) -> (f64, f64) {
        let (_, x, j, dv) = self.sample_cells(u);
        (x, (j as f64 + dv) * (self.y_max / self.ny as f64))
    }

    /// [`PiecewiseConstant2D::sample`] with the cells it draws: (x cell i,
    /// x, y cell j, the position of y within cell j in [0, 1]); y is
    /// `(j + dv) * y_max / ny`, which lies in cell j.
    #[inline(always)]
    pub fn sample_cells(&self, u: [f64; 2]) -> (usize, f64, usize, f64) {
        let v = if u[1].is_finite() {
            u[1].clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.sample_cells_unit_v(u[0], v)
    }

    /// [`PiecewiseConstant2D::sample_cells`] of (u0, v) for a v already
    /// in [0, 1] (a caller that clamped it need not pay twice).
    #[inline(always)]
    pub(crate) fn sample_cells_unit_v(&self, u0: f64, v: f64) -> (usize, f64, usize, f64) {
        let (i, x) = self.marginal.sample_cell(u0);
        let ny = self.ny;
        let row = &self.cdf[i * (ny + 1)..(i + 1) * (ny + 1)];
        // The last j with row[j] <= v (row[0] = 0 <= v), as a binary search
        // finds it: the row is non-decreasing, so that j is the count of
        // row[1..=ny] <= v, counted without branches (a random v would
        // mispredict half of a search's branches; eight compares in SIMD
        // lanes for the bsdf's 8-cell rows).
        let mut j = match <&[f64; 8]>::try_from(&row[1..]) {
            Ok(r) => count_le(r, v),
            Err(_) => row[1..].iter().map(|&c| usize::from(c <= v)).sum(),
        };
        // Below ny, row[j] <= v < row[j + 1]: cell j has mass. Only v at
        // the row's end (1) needs the walk back past cells without any.
        if j >= ny {
            j = ny - 1;
            while row[j + 1] <= row[j] && j > 0 {
                j -= 1;
            }
        }
        let p = row[j + 1] - row[j];
        let dv = if p > 0.0 {
            ((v - row[j]) / p).clamp(0.0, 1.0)
        } else {
            0.5
        };
        // Stay inside cell j, as pdf will find it. Rounding moves y's cell
        // coordinate by a few ulps of j + dv (below 1e-9 for ny < 2^20), so
        // only a dv that close to the cell's ends needs the check (two
        // divisions the common case skips).
        // (|dv - 1/2| against 1/2 - 1e-9, dv never NaN: the same test up
        // to rounding of the bound, by ~1e-16, where the check passes
        // either way.)
        if ((dv - 0.5).abs() >= 0.5 - 1e-9 || self.ny >= 1 << 20)
            && self.y_cell((j as f64 + dv) * (self.y_max / self.ny as f64)) != Some(j)
        {
            return (i, x, j, 0.5);
        }
        (i, x, j, dv)
    }

    /// The y cell of y (None outside [0, y_max)).
    #[inline]
    pub fn y_cell(&self, y: f64) -> Option<usize> {
        if !(y >= 0.0 && y < self.y_max) {
            return None;
        }
        Some(((y / self.y_max * self.ny as f64) as usize).min(self.ny - 1))
    }

    /// Density in cell (i, j) (i from the marginal's `cell_of`, j from `y_cell`).
    #[inline]
    pub fn cell_density(&self, i: usize, j: usize) -> f64 {
        self.marginal.cell_density(i) * self.conditional_probability(i, j) * self.ny as f64
            / self.y_max
    }

    /// Density at (x, y); zero outside the support.
    #[inline]
    pub fn pdf(&self, x: f64, y: f64) -> f64 {
        match (self.marginal.cell_of(x), self.y_cell(y)) {
            (Some(i), Some(j)) => self.cell_density(i, j),
            _ => 0.0,
        }
    }
}

/// How many of the eight entries are at most v (a NaN entry counts not).
#[inline(always)]
fn count_le(r: &[f64; 8], v: f64) -> usize {
    let mut n = 0;
    for &c in r {
        n += usize::from(c <= v);
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_follow_the_cell_masses_and_pdf_integrates_to_one() {
        let mass = [1.0, 0.0, 3.0, 0.0, 0.0, 0.0, 2.0, 2.0, 0.5];
        let d = PiecewiseConstant2D::new(vec![0.0, 0.2, 0.5, 1.0], 3, 3.0, &mass).unwrap();
        let total: f64 = mass.iter().sum();
        let mut counts = [0usize; 9];
        let n = 90_000;
        for k in 0..n {
            // A low-discrepancy lattice: exact enough to compare counts.
            let u = [
                (k as f64 + 0.5) / n as f64,
                ((k * 7919) % n) as f64 / n as f64,
            ];
            let (x, y) = d.sample(u);
            let i = d.marginal().cell_of(x).unwrap();
            let j = d.y_cell(y).unwrap();
            assert!(d.pdf(x, y) > 0.0, "drew a zero cell at {u:?}");
            counts[i * 3 + j] += 1;
        }
        for c in 0..9 {
            let expected = mass[c] / total;
            let got = counts[c] as f64 / n as f64;
            assert!(
                (got - expected).abs() < 2e-3,
                "cell {c}: {got} vs {expected}"
            );
        }
        let widths = [0.2, 0.3, 0.5];
        let integral: f64 = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| d.cell_density(i, j) * widths[i] * 1.0)
            .sum();
        assert!((integral - 1.0).abs() < 1e-12, "{integral}");
        assert_eq!(d.pdf(0.1, 3.0), 0.0);
        assert!(PiecewiseConstant2D::new(vec![0.0, 1.0], 2, 1.0, &[0.0, 0.0]).is_none());
        assert!(PiecewiseConstant2D::new(vec![0.0, 1.0], 2, 1.0, &[f64::NAN, 1.0]).is_none());
    }

    #[test]
    fn v_at_one_draws_the_last_y_cell_with_mass() {
        // Eight y cells (the bsdf's counted search) and three (the general
        // one), each row ending in empty cells.
        for ny in [8, 3] {
            let mut mass = vec![0.0; 2 * ny];
            (mass[0], mass[1], mass[ny]) = (1.0, 1.0, 1.0);
            let d = PiecewiseConstant2D::new(vec![0.0, 0.5, 1.0], ny, 1.0, &mass).unwrap();
            for v in [1.0, 2.0, 1.0 - 1e-12] {
                assert_eq!(d.sample_cells([0.25, v]).2, 1, "ny {ny} v {v}");
                assert_eq!(d.sample_cells([0.75, v]).2, 0, "ny {ny} v {v}");
            }
            assert_eq!(d.sample_cells([0.25, 0.25]).2, 0);
        }
    }
}
