//! Per table entry, the samples that touch it (CSR), coloured so that
//! entries of one colour can be updated in parallel.

use crate::grid::{StencilTable, Weight};
use rayon::prelude::*;

/// For each table entry, the samples that touch it and with which weight
/// (CSR layout), plus a colouring: entries of one colour share no sample, so
/// their element updates are independent and may run in parallel.
#[derive(Clone, Debug, Default)]
pub struct Incidence {
    /// Entry k's samples are `start[k]..start[k + 1]` of `sample`/`weight`.
    pub start: Vec<usize>,
    /// The samples touching each entry.
    pub sample: Vec<u32>,
    /// Their interpolation weights.
    pub weight: Vec<Weight>,
    /// Entries grouped so that no two in a group share a sample.
    pub colors: Vec<Vec<usize>>,
    /// Whether any sample with non-zero weight touches the entry.
    pub has_data: Vec<bool>,
}

impl Incidence {
    /// The CSR range of entry k.
    pub fn entries(&self, k: usize) -> std::ops::Range<usize> {
        self.start[k]..self.start[k + 1]
    }

    pub(super) fn build(cells: usize, stencils: &StencilTable, total_w: &[f64]) -> Self {
        let mut count = vec![0usize; cells];
        for j in 0..stencils.len() {
            for (k, _) in stencils.entries(j) {
                count[k] += 1;
            }
        }
        let mut start = vec![0usize; cells + 1];
        for k in 0..cells {
            start[k + 1] = start[k] + count[k];
        }
        let mut fill = start.clone();
        let mut sample = vec![0u32; start[cells]];
        let mut weight: Vec<Weight> = vec![0.0; start[cells]];
        let mut has_data = vec![false; cells];
        let mut conflict = vec![false; cells * cells];
        for (j, &tw) in total_w.iter().enumerate().take(stencils.len()) {
            for (k, w) in stencils.entries(j) {
                sample[fill[k]] = j as u32;
                weight[fill[k]] = w as Weight;
                fill[k] += 1;
                has_data[k] |= tw > 0.0;
                for (k2, _) in stencils.entries(j) {
                    conflict[k * cells + k2] = true;
                }
            }
        }
        // Greedy colouring in index order: deterministic and, for 1-D linear
        // stencils, the two parities (for bilinear 2-D stencils, four).
        let mut color_of = vec![usize::MAX; cells];
        let mut colors: Vec<Vec<usize>> = Vec::new();
        for k in 0..cells {
            let c = (0..)
                .find(|&c| {
                    colors.get(c).map_or(true, |members: &Vec<usize>| {
                        members.iter().all(|&k2| !conflict[k * cells + k2])
                    })
                })
                .unwrap();
            if c == colors.len() {
                colors.push(Vec::new());
            }
            colors[c].push(k);
            color_of[k] = c;
        }
        Incidence {
            start,
            sample,
            weight,
            colors,
            has_data,
        }
    }
}

/// For each G control point, the samples whose G(theta_i) (weight u) or
/// G(theta_o) (weight v) use it. Both appear in one entry, so a sample
/// occurs at most once per point.
#[derive(Clone, Debug, Default)]
pub struct GIncidence {
    /// Point k's samples are `start[k]..start[k + 1]`.
    pub start: Vec<usize>,
    /// The samples touching each point.
    pub sample: Vec<u32>,
    /// The point's weight in the sample's G(theta_i).
    pub u: Vec<Weight>,
    /// The point's weight in the sample's G(theta_o).
    pub v: Vec<Weight>,
    /// Whether any sample with non-zero weight touches the point.
    pub has_data: Vec<bool>,
}

/// Samples per task of the incidence builds: large enough to amortise a
/// task's per-point counts, small enough to balance two or more threads.
pub(super) const INCIDENCE_CHUNK: usize = 1 << 15;

/// A slice written at distinct indices from parallel tasks.
pub(super) struct DisjointWrites<T>(*mut T, usize);
// SAFETY: writers only touch distinct indices (see `write`).
unsafe impl<T: Send> Sync for DisjointWrites<T> {}
impl<T> DisjointWrites<T> {
    pub(super) fn new(v: &mut [T]) -> Self {
        DisjointWrites(v.as_mut_ptr(), v.len())
    }
    /// SAFETY: no two concurrent calls may pass the same index, and the
    /// slice given to `new` must outlive every call.
    pub(super) unsafe fn write(&self, i: usize, value: T) {
        assert!(i < self.1, "incidence index out of range");
        *self.0.add(i) = value;
    }
}

/// Whether a fit on a [`FitSet`](crate::samples::FitSet) updates G (and needs its sample lists).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GUse {
    /// G is updated: every point's sample list is built.
    #[default]
    Updated,
    /// G is held fixed: only [`GIncidence::has_data`] is filled.
    Fixed,
}

impl GIncidence {
    /// No sample lists, only which points a weighted sample touches (the
    /// same `has_data` as [`GIncidence::build`]), for sets whose G is
    /// held fixed.
    pub(super) fn has_data_only(
        nodes: usize,
        gi: &StencilTable,
        go: &StencilTable,
        total_w: &[f64],
    ) -> Self {
        let mut has_data = vec![false; nodes];
        for (j, _) in total_w.iter().enumerate().filter(|(_, &w)| w > 0.0) {
            for (k, _) in gi.entries(j).chain(go.entries(j)) {
                has_data[k] = true;
            }
        }
        GIncidence {
            start: vec![0; nodes + 1],
            has_data,
            ..Default::default()
        }
    }

    /// The CSR range of point k.
    pub fn entries(&self, k: usize) -> std::ops::Range<usize> {
        self.start[k]..self.start[k + 1]
    }

    /// Built in parallel over chunks of samples: each chunk counts its
    /// entries per point, the counts give every chunk its own slots in each
    /// point's list, and the chunks fill them. The lists are in sample
    /// order, exactly as a serial pass leaves them, for any thread count.
    pub(crate) fn build(
        nodes: usize,
        gi: &StencilTable,
        go: &StencilTable,
        total_w: &[f64],
    ) -> Self {
        const MAX_TOUCHED: usize = 2 * crate::grid::MAX_SUPPORT;
        // The points sample j touches, with its weights in G(theta_i) and G(theta_o).
        let touched = |j: usize, out: &mut [(usize, Weight, Weight); MAX_TOUCHED]| {
            let mut n = 0;
            for (k, w) in gi.entries(j) {
                out[n] = (k, w as Weight, 0.0);
                n += 1;
            }
            for (k, w) in go.entries(j) {
                match out[..n].iter_mut().find(|t| t.0 == k) {
                    Some(t) => t.2 = w as Weight,
                    None => {
                        out[n] = (k, 0.0, w as Weight);
                        n += 1;
                    }
                }
            }
            n
        };
        let n = gi.len();
        let chunks = n.div_ceil(INCIDENCE_CHUNK);
        let chunk = |c: usize| c * INCIDENCE_CHUNK..((c + 1) * INCIDENCE_CHUNK).min(n);
        // Per chunk: entries per point, and whether a weighted sample touches it.
        let counts: Vec<(Vec<usize>, Vec<bool>)> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let mut buf = [(usize::MAX, 0.0, 0.0); MAX_TOUCHED];
                let (mut count, mut has) = (vec![0usize; nodes], vec![false; nodes]);
                for j in chunk(c) {
                    let used = touched(j, &mut buf);
                    for t in &buf[..used] {
                        count[t.0] += 1;
                        has[t.0] |= total_w[j] > 0.0;
                    }
                }
                (count, has)
            })
            .collect();
        let mut start = vec![0usize; nodes + 1];
        let mut has_data = vec![false; nodes];
        for (count, has) in &counts {
            for k in 0..nodes {
                start[k + 1] += count[k];
                has_data[k] |= has[k];
            }
        }
        for k in 0..nodes {
            start[k + 1] += start[k];
        }
        // Chunk c's first slot in point k's list.
        let mut first = Vec::with_capacity(chunks);
        let mut at = start[..nodes].to_vec();
        for (count, _) in &counts {
            first.push(at.clone());
            for k in 0..nodes {
                at[k] += count[k];
            }
        }
        let total = start[nodes];
        let (mut sample, mut u, mut v) = (vec![0u32; total], vec![0.0; total], vec![0.0; total]);
        let (ws, wu, wv) = (
            DisjointWrites::new(&mut sample),
            DisjointWrites::new(&mut u),
            DisjointWrites::new(&mut v),
        );
        first.into_par_iter().enumerate().for_each(|(c, mut fill)| {
            let mut buf = [(usize::MAX, 0.0, 0.0); MAX_TOUCHED];
            for j in chunk(c) {
                let used = touched(j, &mut buf);
                for &(k, uk, vk) in &buf[..used] {
                    let e = fill[k];
                    fill[k] += 1;
                    // SAFETY: slots fill[k] of chunk c are its own (counted
                    // above), and the vectors outlive this loop.
                    unsafe {
                        ws.write(e, j as u32);
                        wu.write(e, uk);
                        wv.write(e, vk);
                    }
                }
            }
        });
        GIncidence {
            start,
            sample,
            u,
            v,
            has_data,
        }
    }
}
