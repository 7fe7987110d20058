//! Deterministic parallel sums: fixed-size chunks whose partial results
//! are added in chunk order, the same bits for any thread count.

/// Deterministic parallel sum of `f` over 0..n, in fixed chunks.
pub(crate) fn chunked_sum<const K: usize>(
    n: usize,
    f: impl Fn(std::ops::Range<usize>) -> [f64; K] + Sync,
) -> [f64; K] {
    use rayon::prelude::*;
    let chunks = n.div_ceil(CHUNK);
    if chunks <= 1 {
        // One chunk: the same sum without a parallel dispatch (a G pass
        // makes 540 such sums a sweep; on a coarse level most are this small).
        return sum_in_order([f(0..n)]);
    }
    let partial: Vec<[f64; K]> = (0..chunks)
        .into_par_iter()
        .map(|c| f(c * CHUNK..((c + 1) * CHUNK).min(n)))
        .collect();
    sum_in_order(partial)
}

/// [`chunked_sum`] fused with a pass that writes `items` (one per sample):
/// `f(start, chunk)` updates the chunk of samples from `start` and returns
/// its partial sums. Same chunks and summation order as [`chunked_sum`], so
/// the total is bit-identical to a separate [`chunked_sum`] pass after it.
pub(crate) fn chunked_sum_mut<T: Send, const K: usize>(
    items: &mut [T],
    f: impl Fn(usize, &mut [T]) -> [f64; K] + Sync,
) -> [f64; K] {
    use rayon::prelude::*;
    let partial: Vec<[f64; K]> = items
        .par_chunks_mut(CHUNK)
        .enumerate()
        .map(|(c, chunk)| f(c * CHUNK, chunk))
        .collect();
    sum_in_order(partial)
}

/// The chunks' partial sums added in chunk order (the fixed order that
/// makes the reductions independent of the thread count).
fn sum_in_order<const K: usize>(partial: impl IntoIterator<Item = [f64; K]>) -> [f64; K] {
    let mut total = [0.0; K];
    for p in partial {
        for k in 0..K {
            total[k] += p[k];
        }
    }
    total
}

/// Fixed chunk size of every parallel reduction (see the module notes).
pub(crate) const CHUNK: usize = 4096;
