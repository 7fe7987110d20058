//! The (d, s) solve's Gram and right-hand-side sums (scalar; the AVX2
//! version is in `avx`).

use super::options::MAX_LOBES;
use super::state::{basis_at, Cache};
use crate::samples::FitSet;

/// Basis functions of the (d, s) solve at most, and its sums' count.
pub(crate) const MAXK: usize = MAX_LOBES + 1;

pub(crate) const SIZE: usize = 3 * (MAXK * MAXK + MAXK);

/// What the (d, s) solve's sums read.
#[derive(Clone, Copy)]
pub(crate) struct GramInput<'a> {
    pub set: &'a FitSet,
    pub cache: &'a [Cache],
    pub basis: &'a Option<Vec<[f64; 3]>>,
    pub masking: crate::model::Masking,
}

impl GramInput<'_> {
    /// Sample j's basis values per channel (b_0 the diffuse factor, b_m =
    /// F D G G / (cos cos) of lobe m, 0 past the lobes), weight and value.
    #[inline(always)]
    pub(crate) fn sample<const LOBES: usize>(&self, j: usize) -> [([f64; MAXK], f64, f64); 3] {
        let c = &self.cache[j];
        let p: [f64; LOBES] =
            std::array::from_fn(|m| c.lobe_product(m, self.set.inv_cc[j], self.masking));
        std::array::from_fn(|ch| {
            let mut b = [0.0; MAXK];
            b[0] = basis_at(self.basis, j, ch);
            for m in 0..LOBES {
                b[m + 1] = c.fv[ch] * p[m];
            }
            (b, self.set.w[j][ch], self.set.y[j][ch])
        })
    }
}

/// The (d, s) solve's Gram and right-hand-side sums of the samples in
/// `range`: per channel, the upper triangle of sum w b_a b_b at
/// `ch * (MAXK * MAXK + MAXK) + a * MAXK + b` (a <= b), then sum w b_a y.
#[inline(always)]
pub(crate) fn gram_sums<const LOBES: usize>(
    g: GramInput,
    range: std::ops::Range<usize>,
) -> [f64; SIZE] {
    let k = LOBES + 1;
    let mut acc = [0.0; SIZE];
    for j in range {
        for (ch, (b, w, y)) in g.sample::<LOBES>(j).into_iter().enumerate() {
            let base = ch * (MAXK * MAXK + MAXK);
            for a in 0..k {
                let wb = w * b[a];
                for bb in a..k {
                    acc[base + a * MAXK + bb] += wb * b[bb];
                }
                acc[base + MAXK * MAXK + a] += wb * y;
            }
        }
    }
    acc
}
