//! Interpolation stencils: a factor value as a weighted sum of table entries.
//!
//! [`Stencil`] is one stencil on the stack (up to [`MAX_SUPPORT`] slots, as
//! evaluation and set-up build them); [`StencilTable`] stores one stencil per
//! sample for one factor as structure-of-arrays with a fixed width per
//! factor (2 for a linear 1-D table, 4 for Catmull-Rom or bilinear, 8 for
//! Catmull-Rom x linear), so a fit keeps exactly the slots its factor needs.
//! A table stores its weights as [`Weight`] (f32): the fit's model is then
//! interpolated with weights rounded to 2^-24 relative, far below any
//! measurement's precision, and every sum over them still runs in f64.

/// The most slots a stencil may have (Catmull-Rom x linear: 4 x 2).
pub const MAX_SUPPORT: usize = 8;

/// A stored interpolation weight (in [`StencilTable`] and the sample set's
/// incidence lists): f32 halves the largest arrays of a fit's memory, and
/// readers widen it to f64 before any arithmetic.
pub type Weight = f32;

/// Up to [`MAX_SUPPORT`] (index, weight) slots; slots past `len` are unused
/// and a used slot may have weight 0 (it is then skipped). Sums read the
/// slots in order, which keeps every fit's arithmetic in a fixed order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stencil {
    len: u8,
    idx: [u32; MAX_SUPPORT],
    w: [f64; MAX_SUPPORT],
}

impl Default for Stencil {
    fn default() -> Self {
        Stencil::empty(0)
    }
}

impl Stencil {
    /// `len` slots, all of weight 0.
    pub fn empty(len: usize) -> Self {
        assert!(
            len <= MAX_SUPPORT,
            "a stencil has at most {MAX_SUPPORT} slots"
        );
        Stencil {
            len: len as u8,
            idx: [0; MAX_SUPPORT],
            w: [0.0; MAX_SUPPORT],
        }
    }

    /// Entry i with weight 1.
    pub fn single(i: usize) -> Self {
        let mut s = Stencil::empty(1);
        s.set(0, i, 1.0);
        s
    }

    /// Two entries.
    pub fn pair(i: usize, wi: f64, j: usize, wj: f64) -> Self {
        let mut s = Stencil::empty(2);
        s.set(0, i, wi);
        s.set(1, j, wj);
        s
    }

    /// Set slot `slot` (which must be below `len`).
    #[inline]
    pub fn set(&mut self, slot: usize, index: usize, weight: f64) {
        debug_assert!(slot < self.len as usize);
        self.idx[slot] = index as u32;
        self.w[slot] = weight;
    }

    /// Append a slot.
    #[inline]
    pub fn push(&mut self, index: usize, weight: f64) {
        let slot = self.len as usize;
        assert!(slot < MAX_SUPPORT, "stencil support exceeds {MAX_SUPPORT}");
        self.len += 1;
        self.set(slot, index, weight);
    }

    /// Number of slots (used or of weight 0).
    pub fn slots(&self) -> usize {
        self.len as usize
    }

    /// The interpolated value of a table.
    #[inline]
    pub fn apply(&self, values: &[f64]) -> f64 {
        let mut s = 0.0;
        for k in 0..self.len as usize {
            let w = self.w[k];
            if w != 0.0 {
                s += w * values[self.idx[k] as usize];
            }
        }
        s
    }

    /// [`Stencil::apply`] on an f32 table (a model's stored form).
    #[inline]
    pub fn apply_f32(&self, values: &[f32]) -> f64 {
        let mut s = 0.0;
        for k in 0..self.len as usize {
            let w = self.w[k];
            if w != 0.0 {
                s += w * values[self.idx[k] as usize] as f64;
            }
        }
        s
    }

    /// The non-zero entries, in slot order.
    pub fn entries(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.idx[..self.len as usize]
            .iter()
            .zip(&self.w[..self.len as usize])
            .filter(|(_, &w)| w != 0.0)
            .map(|(&i, &w)| (i as usize, w))
    }

    /// The tensor product with a second-axis stencil on a row-major table
    /// with `cols` columns: entry (a, b) is a * cols + b, weight w_a w_b,
    /// slots in (first-axis slot, second-axis slot) order.
    pub fn outer(&self, other: &Stencil, cols: usize) -> Stencil {
        let mut out = Stencil::empty(0);
        for a in 0..self.len as usize {
            for b in 0..other.len as usize {
                out.push(
                    self.idx[a] as usize * cols + other.idx[b] as usize,
                    self.w[a] * other.w[b],
                );
            }
        }
        out
    }
}

/// One stencil per sample for one factor, `width` slots each
/// (structure-of-arrays: sample j's slots are `j * width .. (j + 1) * width`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StencilTable {
    /// Slots per sample.
    pub width: usize,
    /// Table entry of each slot.
    pub idx: Vec<u32>,
    /// Weight of each slot (0: unused).
    pub w: Vec<Weight>,
}

impl StencilTable {
    /// An empty table of `width`-slot stencils with room for `n` samples.
    pub fn with_capacity(width: usize, n: usize) -> Self {
        StencilTable {
            width,
            idx: Vec::with_capacity(width * n),
            w: Vec::with_capacity(width * n),
        }
    }

    /// Append a sample's stencil. Panics if it has more non-zero slots than
    /// `width`; its used slots keep their order and zero slots may be dropped.
    pub fn push(&mut self, st: &Stencil) {
        let start = self.w.len();
        let mut used = 0;
        for k in 0..st.len as usize {
            let w = st.w[k];
            if k < self.width {
                self.idx.push(st.idx[k]);
                self.w.push(w as Weight);
                used += 1;
            } else {
                assert!(w == 0.0, "stencil wider than its table ({})", self.width);
            }
        }
        for _ in used..self.width {
            self.idx.push(0);
            self.w.push(0.0);
        }
        debug_assert_eq!(self.w.len(), start + self.width);
    }

    /// The table of samples `0..n` whose stencils `stencil(j)` gives, as
    /// [`push`](Self::push) would store them one by one; built in parallel
    /// (the result does not depend on the thread count).
    pub fn from_fn(width: usize, n: usize, stencil: impl Fn(usize) -> Stencil + Sync) -> Self {
        use rayon::prelude::*;
        // Samples per task: large enough to amortise the task, small enough to balance.
        const CHUNK: usize = 4096;
        let mut idx = vec![0u32; width * n];
        let mut w: Vec<Weight> = vec![0.0; width * n];
        idx.par_chunks_mut(width * CHUNK)
            .zip(w.par_chunks_mut(width * CHUNK))
            .enumerate()
            .for_each(|(c, (idx, w))| {
                for (k, (idx, w)) in idx.chunks_mut(width).zip(w.chunks_mut(width)).enumerate() {
                    Self::store(&stencil(c * CHUNK + k), idx, w);
                }
            });
        StencilTable { width, idx, w }
    }

    /// Write a stencil into one sample's zeroed slots (`idx` and `w` of the
    /// table's width), as [`from_fn`](Self::from_fn) stores it: slots past
    /// the stencil's length stay 0. Panics if a non-zero slot does not fit.
    #[inline]
    pub fn store(st: &Stencil, idx: &mut [u32], w: &mut [Weight]) {
        let width = idx.len().min(w.len());
        for s in 0..st.len as usize {
            if s < width {
                idx[s] = st.idx[s];
                w[s] = st.w[s] as Weight;
            } else {
                assert!(st.w[s] == 0.0, "stencil wider than its table ({width})");
            }
        }
    }

    /// The table in consecutive pieces of `per` samples (the last may be
    /// shorter), for parallel writers that [`StencilRows::store`] each
    /// sample's stencil.
    pub fn par_pieces_mut(
        &mut self,
        per: usize,
    ) -> impl rayon::iter::IndexedParallelIterator<Item = StencilRows<'_>> {
        use rayon::prelude::*;
        let width = self.width;
        let slots = (per * width).max(1);
        self.idx
            .par_chunks_mut(slots)
            .zip(self.w.par_chunks_mut(slots))
            .map(move |(idx, w)| StencilRows { width, idx, w })
    }

    /// A table of `n` samples' zeroed slots, to be filled by [`store`](Self::store).
    pub fn zeroed(width: usize, n: usize) -> Self {
        StencilTable {
            width,
            idx: vec![0; width * n],
            w: vec![0.0; width * n],
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.w.len().checked_div(self.width).unwrap_or(0)
    }

    /// Whether the table holds no sample.
    pub fn is_empty(&self) -> bool {
        self.w.is_empty()
    }

    /// Sample j's interpolated value of a table (same order as [`Stencil::apply`]).
    #[inline]
    pub fn apply(&self, j: usize, values: &[f64]) -> f64 {
        // The common widths get a loop the compiler unrolls.
        match self.width {
            2 => self.apply_n::<2>(j, values),
            4 => self.apply_n::<4>(j, values),
            8 => self.apply_n::<8>(j, values),
            n => {
                let base = j * n;
                sum_slots(&self.idx[base..base + n], &self.w[base..base + n], values)
            }
        }
    }

    #[inline(always)]
    fn apply_n<const N: usize>(&self, j: usize, values: &[f64]) -> f64 {
        let (idx, w) = self.row::<N>(j);
        sum_slots(idx, w, values)
    }

    /// Sample j's slots as fixed-size arrays (`N` must equal `width`), for
    /// loops that dispatch on the width once instead of per sample.
    #[inline(always)]
    pub fn row<const N: usize>(&self, j: usize) -> (&[u32; N], &[Weight; N]) {
        debug_assert_eq!(N, self.width);
        let base = j * N;
        (
            self.idx[base..base + N].try_into().unwrap(),
            self.w[base..base + N].try_into().unwrap(),
        )
    }

    /// [`StencilTable::apply`] of a row from [`StencilTable::row`].
    #[inline(always)]
    pub fn apply_row<const N: usize>(row: (&[u32; N], &[Weight; N]), values: &[f64]) -> f64 {
        sum_slots(row.0, row.1, values)
    }

    /// Sample j's non-zero entries, in slot order.
    pub fn entries(&self, j: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = j * self.width..(j + 1) * self.width;
        self.idx[r.clone()]
            .iter()
            .zip(&self.w[r])
            .filter(|(_, &w)| w != 0.0)
            .map(|(&i, &w)| (i as usize, f64::from(w)))
    }

    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        self.idx.len() * 4 + self.w.len() * std::mem::size_of::<Weight>()
    }
}

/// Consecutive samples' slots of a [`StencilTable`], written in place.
pub struct StencilRows<'a> {
    width: usize,
    idx: &'a mut [u32],
    w: &'a mut [Weight],
}

impl StencilRows<'_> {
    /// Store the stencil of the piece's k-th sample (its slots must still
    /// be zero), as [`StencilTable::store`].
    #[inline]
    pub fn store(&mut self, k: usize, st: &Stencil) {
        let r = k * self.width..(k + 1) * self.width;
        StencilTable::store(st, &mut self.idx[r.clone()], &mut self.w[r]);
    }
}

#[inline(always)]
fn sum_slots(idx: &[u32], w: &[Weight], values: &[f64]) -> f64 {
    let mut s = 0.0;
    for (&i, &w) in idx.iter().zip(w) {
        if w != 0.0 {
            s += f64::from(w) * values[i as usize];
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_rows_apply_like_their_stencils() {
        let values: Vec<f64> = (0..20).map(|k| 1.0 + k as f64 * 0.37).collect();
        let a = Stencil::pair(3, 0.25, 4, 0.75);
        let b = Stencil::pair(1, 0.5, 2, 0.5);
        let ab = a.outer(&b, 4);
        let mut t = StencilTable::with_capacity(4, 2);
        t.push(&ab);
        t.push(&Stencil::single(7));
        assert_eq!(t.len(), 2);
        assert_eq!(t.apply(0, &values), ab.apply(&values));
        assert_eq!(t.apply(1, &values), values[7]);
        let e: Vec<_> = t.entries(0).collect();
        assert_eq!(e, vec![(13, 0.125), (14, 0.125), (17, 0.375), (18, 0.375)]);
    }
}
