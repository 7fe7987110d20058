//! The order of the generic build: sort keys that put reciprocal partners
//! side by side, and a parallel bucket sort over them.

use super::incidence::DisjointWrites;
use super::weighting::round_to_i64;
use rayon::prelude::*;

/// A sample's sort key: (theta_i, theta_o) ordered so that theta_i <=
/// theta_o, then theta_h, theta_d, each quantised to 1e-7 rad; packed
/// 32 bits a component (order-preserving for any angle below 214 rad), so
/// the sort moves 24-byte (key, index) pairs instead of whole records.
pub(super) fn sort_key(a: &npf_data_loaders::geometry::Angles) -> Key {
    let q = |x: f64| key_part(x) as u128;
    let (lo, hi) = if a.theta_i > a.theta_o {
        (a.theta_o, a.theta_i)
    } else {
        (a.theta_i, a.theta_o)
    };
    Key::from(q(lo) << 96 | q(hi) << 64 | q(a.theta_h) << 32 | q(a.theta_d))
}

/// One component of [`sort_key`]: an angle quantised to 1e-7 rad, as an
/// order-preserving u32.
#[inline]
pub(super) fn key_part(x: f64) -> u32 {
    let v = round_to_i64(x * 1e7).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
    v as u32 ^ 0x8000_0000
}

/// A 128-bit sort key as two 64-bit halves, high first: the same order as
/// the u128, but 8-byte aligned, so a (key, index) pair takes 24 bytes, not
/// 32, through the key pass, the sort and the merge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Key(pub(super) u64, pub(super) u64);

impl From<u128> for Key {
    fn from(k: u128) -> Self {
        Key((k >> 64) as u64, k as u64)
    }
}

/// Input samples per chunk of the key pass (and of the bucket sort's passes).
pub(super) const KEY_CHUNK: usize = 1 << 16;

/// The pairs of `chunks` (concatenated) in ascending order, as
/// `par_sort_unstable` leaves them (the pairs are distinct, so the order
/// is total and unique). A counting pass distributes them into buckets by
/// the top 32 bits of the key (theta_i's quantised value), chunk by chunk
/// in input order, then each bucket (a few hundred pairs, cache resident)
/// is sorted on its own, in parallel: about half the work of a comparison
/// sort of the whole array.
pub(super) fn bucket_sort(chunks: Vec<Vec<(Key, u32)>>) -> Vec<(Key, u32)> {
    let top = |p: &(Key, u32)| (p.0 .0 >> 32) as u32;
    let len: usize = chunks.iter().map(Vec::len).sum();
    let (lo, hi) = chunks
        .par_iter()
        .flat_map_iter(|c| c.iter().map(|p| (top(p), top(p))))
        .reduce(|| (u32::MAX, 0), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    if len < 2 * KEY_CHUNK || lo >= hi {
        let mut pairs = chunks.concat();
        pairs.par_sort_unstable();
        return pairs;
    }
    // About 256 pairs a bucket; the shift keeps the bucket monotone in the key.
    let want = (len / 256).next_power_of_two().min(1 << 16) as u64;
    let span = u64::from(hi - lo) + 1;
    let shift = (64 - (span.div_ceil(want)).leading_zeros()).min(31);
    let buckets = ((span - 1) >> shift) as usize + 1;
    let bucket = |p: &(Key, u32)| ((top(p) - lo) >> shift) as usize;
    let counts: Vec<Vec<usize>> = chunks
        .par_iter()
        .map(|c| {
            let mut n = vec![0usize; buckets];
            for p in c.iter() {
                n[bucket(p)] += 1;
            }
            n
        })
        .collect();
    // Chunk c's first slot in bucket b: the bucket's start plus the pairs
    // of earlier chunks in it.
    let mut sizes = vec![0usize; buckets];
    let mut firsts = Vec::with_capacity(chunks.len());
    for n in &counts {
        firsts.push(sizes.clone());
        for (s, k) in sizes.iter_mut().zip(n) {
            *s += k;
        }
    }
    let mut start = 0;
    let mut bucket_start = vec![0usize; buckets];
    for (b, &size) in sizes.iter().enumerate() {
        bucket_start[b] = start;
        start += size;
    }
    let mut out = vec![(Key::default(), 0u32); len];
    {
        let slots = DisjointWrites::new(&mut out);
        chunks.par_iter().zip(firsts).for_each(|(c, mut fill)| {
            for p in c.iter() {
                let b = bucket(p);
                // SAFETY: chunk c's slots in each bucket are its own.
                unsafe { slots.write(bucket_start[b] + fill[b], *p) };
                fill[b] += 1;
            }
        });
    }
    drop(chunks);
    let mut parts = Vec::with_capacity(buckets);
    let mut rest = &mut out[..];
    for &size in &sizes {
        let (part, tail) = rest.split_at_mut(size);
        parts.push(part);
        rest = tail;
    }
    parts.into_par_iter().for_each(|part| part.sort_unstable());
    out
}

/// Merged samples per task of the set's main pass.
pub(super) const PIECE: usize = 4096;

/// How many runs ahead the main pass prefetches its input records.
pub(super) const PREFETCH_RUNS: usize = 16;

/// Ask for input sample `index`'s record (88 bytes: two or three cache lines) to be
/// brought into cache; a hint only, with no effect on any value.
#[inline(always)]
pub(super) fn prefetch_sample(samples: &[npf_data_loaders::MeasuredSample], index: u32) {
    #[cfg(target_arch = "x86_64")]
    if let Some(s) = samples.get(index as usize) {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = (s as *const npf_data_loaders::MeasuredSample).cast::<i8>();
        let last = std::mem::size_of::<npf_data_loaders::MeasuredSample>() - 1;
        // SAFETY: a prefetch reads nothing and faults on no address; the
        // addresses are the record's first byte, 64 bytes on and last byte.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64.min(last)));
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(last));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (samples, index);
}
