//! The solver's hottest per-sample loops in AVX registers, where the
//! processor has AVX2 (detected at run time; the default target has SSE2
//! only). Each is bit-identical to its scalar loop: every sum gets the same
//! products in the same order (no fused multiply-add); only the packing
//! changes.
//!
//! - The G pass ([`super::g_update`]) four entries at a time: one entry per
//!   lane, and the entries' terms added to the even and odd sums in the
//!   scalar loop's order (entry 4k and 4k+2 to the even sum, 4k+1 and 4k+3
//!   to the odd one, one after the other). On white-fabric's coarse level
//!   the pass's per-entry loops run 0.55 G instructions instead of 0.97
//!   (BENCHMARKS.md as of 4d8d1ee, issue 15, c26).
//! - The (d, s) solve's Gram sums ([`super::updates`]): one row of the
//!   4 x 4 Gram matrix (3 lobes and the diffuse basis) per register.

/// Whether the kernels below may run here (the callers' scalar loops are
/// the only path on other architectures).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx2")
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use crate::grid::Weight;
    use crate::solver::g_work::{cubic_terms, GWork};
    use crate::solver::gram::{GramInput, MAXK, SIZE};
    use std::arch::x86_64::*;

    // GWork's four f64 fields are one 32-byte row.
    const _: () = assert!(std::mem::size_of::<GWork>() == 32);

    /// Rows [a0 a1 a2 a3] .. [d0 d1 d2 d3] to columns [a0 b0 c0 d0] ..
    /// [a3 b3 c3 d3] (its own inverse).
    #[inline(always)]
    unsafe fn transpose(a: __m256d, b: __m256d, c: __m256d, d: __m256d) -> [__m256d; 4] {
        let (t0, t1) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
        let (t2, t3) = (_mm256_unpacklo_pd(c, d), _mm256_unpackhi_pd(c, d));
        [
            _mm256_permute2f128_pd::<0x20>(t0, t2),
            _mm256_permute2f128_pd::<0x20>(t1, t3),
            _mm256_permute2f128_pd::<0x31>(t0, t2),
            _mm256_permute2f128_pd::<0x31>(t1, t3),
        ]
    }

    /// Four weights widened to f64 (exact).
    #[inline(always)]
    unsafe fn widen(w: &[Weight]) -> __m256d {
        _mm256_cvtps_pd(_mm_loadu_ps(w[..4].as_ptr()))
    }

    #[inline(always)]
    unsafe fn row(x: *const GWork) -> __m256d {
        _mm256_loadu_pd(x as *const f64)
    }

    /// The quartic's coefficient sums over the entries `(sample, u, v)`
    /// (equal lengths): what the scalar loop of `update_g` returns.
    ///
    /// # Safety
    /// AVX2 must be available ([`super::available`]).
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn cubic_sums(
        work: &[GWork],
        sample: &[u32],
        u: &[Weight],
        v: &[Weight],
    ) -> [f64; 4] {
        let n = sample.len().min(u.len()).min(v.len());
        let two = _mm256_set1_pd(2.0);
        let (mut even, mut odd) = (_mm256_setzero_pd(), _mm256_setzero_pd());
        let mut k = 0;
        while k + 4 <= n {
            let s = &sample[k..k + 4];
            // Indexing checks each sample against the work rows.
            let [gi, go, sr, sa] = transpose(
                row(&work[s[0] as usize]),
                row(&work[s[1] as usize]),
                row(&work[s[2] as usize]),
                row(&work[s[3] as usize]),
            );
            let (uu, vv) = (widen(&u[k..]), widen(&v[k..]));
            // As the scalar `cubic_terms`, lane by lane.
            let p1 = _mm256_add_pd(_mm256_mul_pd(gi, vv), _mm256_mul_pd(go, uu));
            let p2 = _mm256_mul_pd(uu, vv);
            let sr2 = _mm256_mul_pd(two, sr);
            let c0 = _mm256_mul_pd(sr2, p1);
            let c1 = _mm256_add_pd(
                _mm256_mul_pd(_mm256_mul_pd(sa, p1), p1),
                _mm256_mul_pd(sr2, p2),
            );
            let c2 = _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(two, sa), p1), p2);
            let c3 = _mm256_mul_pd(_mm256_mul_pd(sa, p2), p2);
            let [e0, e1, e2, e3] = transpose(c0, c1, c2, c3);
            even = _mm256_add_pd(even, e0);
            odd = _mm256_add_pd(odd, e1);
            even = _mm256_add_pd(even, e2);
            odd = _mm256_add_pd(odd, e3);
            k += 4;
        }
        let (mut ev, mut od) = ([0.0; 4], [0.0; 4]);
        _mm256_storeu_pd(ev.as_mut_ptr(), even);
        _mm256_storeu_pd(od.as_mut_ptr(), odd);
        // The rest as the scalar loop: a pair, then a last entry (even).
        while k + 2 <= n {
            cubic_terms(&work[sample[k] as usize], u[k], v[k], &mut ev);
            cubic_terms(&work[sample[k + 1] as usize], u[k + 1], v[k + 1], &mut od);
            k += 2;
        }
        if k < n {
            cubic_terms(&work[sample[k] as usize], u[k], v[k], &mut ev);
        }
        std::array::from_fn(|i| ev[i] + od[i])
    }

    /// The step `t` applied to the entries `(sample, u, v)` of one point:
    /// each sample's G values and S_r moved as by the scalar loop of
    /// `update_g`.
    ///
    /// # Safety
    /// AVX2 must be available, `work` must point to `len` rows, the
    /// `sample` indices must be distinct, and no other thread may touch
    /// those rows meanwhile. Returns how many entries it applied (a
    /// multiple of four; the scalar loop does the rest).
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn apply_step(
        (work, len): (*mut GWork, usize),
        sample: &[u32],
        u: &[Weight],
        v: &[Weight],
        t: f64,
    ) -> usize {
        let n = sample.len().min(u.len()).min(v.len());
        let tt = _mm256_set1_pd(t);
        let mut k = 0;
        while k + 4 <= n {
            let p: [*mut GWork; 4] = std::array::from_fn(|i| {
                let j = sample[k + i] as usize;
                assert!(j < len, "G incidence beyond the samples");
                work.add(j)
            });
            let [gi, go, sr, sa] = transpose(row(p[0]), row(p[1]), row(p[2]), row(p[3]));
            let (uu, vv) = (widen(&u[k..]), widen(&v[k..]));
            let p1 = _mm256_add_pd(_mm256_mul_pd(gi, vv), _mm256_mul_pd(go, uu));
            let p2 = _mm256_mul_pd(uu, vv);
            // x.sr += x.sa * (p1 * t + p2 * t * t)
            let step = _mm256_add_pd(
                _mm256_mul_pd(p1, tt),
                _mm256_mul_pd(_mm256_mul_pd(p2, tt), tt),
            );
            let sr = _mm256_add_pd(sr, _mm256_mul_pd(sa, step));
            let gi = _mm256_add_pd(gi, _mm256_mul_pd(uu, tt));
            let go = _mm256_add_pd(go, _mm256_mul_pd(vv, tt));
            let rows = transpose(gi, go, sr, sa);
            for i in 0..4 {
                _mm256_storeu_pd(p[i] as *mut f64, rows[i]);
            }
            k += 4;
        }
        k
    }

    /// `updates::gram_sums` with each Gram row's products in one register
    /// (the lower triangle's lanes are computed and discarded).
    ///
    /// # Safety
    /// AVX2 must be available ([`super::available`]).
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn gram_sums<const LOBES: usize>(
        g: GramInput,
        range: std::ops::Range<usize>,
    ) -> [f64; SIZE] {
        const { assert!(MAXK == 4, "a Gram row is one register") };
        let k = LOBES + 1;
        let mut rows = [[_mm256_setzero_pd(); MAXK]; 3];
        let mut rhs = [_mm256_setzero_pd(); 3];
        for j in range {
            for (ch, (b, w, y)) in g.sample::<LOBES>(j).into_iter().enumerate() {
                let bv = _mm256_loadu_pd(b.as_ptr());
                let mut wb = [0.0; MAXK];
                for a in 0..k {
                    wb[a] = w * b[a];
                    let row = _mm256_mul_pd(_mm256_set1_pd(wb[a]), bv);
                    rows[ch][a] = _mm256_add_pd(rows[ch][a], row);
                }
                let r = _mm256_mul_pd(_mm256_loadu_pd(wb.as_ptr()), _mm256_set1_pd(y));
                rhs[ch] = _mm256_add_pd(rhs[ch], r);
            }
        }
        let mut acc = [0.0; SIZE];
        for ch in 0..3 {
            let base = ch * (MAXK * MAXK + MAXK);
            let mut lanes = [0.0; MAXK];
            for a in 0..k {
                _mm256_storeu_pd(lanes.as_mut_ptr(), rows[ch][a]);
                acc[base + a * MAXK + a..base + a * MAXK + k].copy_from_slice(&lanes[a..k]);
            }
            _mm256_storeu_pd(lanes.as_mut_ptr(), rhs[ch]);
            acc[base + MAXK * MAXK..base + MAXK * MAXK + k].copy_from_slice(&lanes[..k]);
        }
        acc
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x86::{apply_step, cubic_sums, gram_sums};

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::grid::Weight;
    use crate::solver::g_work::{apply_entry, cubic_sums as scalar_sums, GWork};

    /// Rows, weights and a scrambled list of distinct samples from a fixed
    /// generator (values over many magnitudes, some zero).
    fn case(
        rows: usize,
        entries: usize,
        seed: u64,
    ) -> (Vec<GWork>, Vec<u32>, Vec<Weight>, Vec<Weight>) {
        let mut z = seed;
        let mut next = || {
            z = z
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (z >> 11) as f64 / (1u64 << 53) as f64
        };
        let val = |r: f64| {
            if r < 0.1 {
                0.0
            } else {
                (r - 0.5) * 10f64.powf(8.0 * r - 4.0)
            }
        };
        let work: Vec<GWork> = (0..rows)
            .map(|_| GWork {
                gi: val(next()),
                go: val(next()),
                sr: val(next()),
                sa: val(next()).abs(),
            })
            .collect();
        let mut sample: Vec<u32> = (0..rows as u32).collect();
        for i in (1..rows).rev() {
            sample.swap(i, (next() * (i + 1) as f64) as usize % (i + 1));
        }
        sample.truncate(entries);
        let u = (0..entries).map(|_| next() as f32 - 0.2).collect();
        let v = (0..entries).map(|_| next() as f32 - 0.2).collect();
        (work, sample, u, v)
    }

    #[test]
    fn vector_kernels_are_bit_identical_to_the_scalar_loops() {
        if !available() {
            return;
        }
        for entries in (0..14).chain([97, 1000]) {
            let (work, sample, u, v) = case(1200, entries, 7 + entries as u64);
            let want = scalar_sums(&work, &sample, &u, &v);
            // SAFETY: AVX2 was detected.
            let got = unsafe { cubic_sums(&work, &sample, &u, &v) };
            assert_eq!(
                got.map(f64::to_bits),
                want.map(f64::to_bits),
                "{entries} entries"
            );

            let t = -0.37;
            let mut scalar = work.clone();
            for ((&j, &u), &v) in sample.iter().zip(&u).zip(&v) {
                apply_entry(&mut scalar[j as usize], u, v, t);
            }
            let mut vector = work.clone();
            // SAFETY: AVX2 was detected; the samples are distinct and in range.
            let k = unsafe { apply_step((vector.as_mut_ptr(), vector.len()), &sample, &u, &v, t) };
            assert_eq!(k, entries / 4 * 4);
            for ((&j, &u), &v) in sample[k..].iter().zip(&u[k..]).zip(&v[k..]) {
                apply_entry(&mut vector[j as usize], u, v, t);
            }
            let bits = |w: &[GWork]| -> Vec<[u64; 4]> {
                w.iter()
                    .map(|x| [x.gi, x.go, x.sr, x.sa].map(f64::to_bits))
                    .collect()
            };
            assert!(bits(&scalar) == bits(&vector), "{entries} entries");
        }
    }

    #[test]
    fn gram_sums_are_bit_identical_to_the_scalar_loop() {
        use crate::model::{Layout, Masking};
        use crate::samples::{FitSet, SampleOptions};
        use crate::solver::gram::{gram_sums as scalar, GramInput};
        use crate::solver::state::Cache;
        if !available() {
            return;
        }
        let brdf = crate::synth::GgxLambert {
            kd: [0.3, 0.2, 0.1],
            f0: [0.9, 0.6, 0.3],
            alpha: 0.2,
        };
        let samples = crate::coarse::decimate(&brdf.table().samples("t"), 64);
        let set = FitSet::build(&samples, Layout::default(), SampleOptions::default()).unwrap();
        let (work, ..) = case(3 * set.len(), 0, 11);
        let v = |j: usize, i: usize| [work[j].gi, work[j].go, work[j].sr, work[j].sa][i % 4];
        let cache: Vec<Cache> = (0..set.len())
            .map(|j| Cache {
                dv: [v(j, 0).abs(), v(j, 1).abs(), v(j, 2).abs()],
                gi: [
                    v(j + set.len(), 0),
                    v(j + set.len(), 1),
                    v(j + set.len(), 2),
                ],
                go: [v(j + set.len(), 3), v(j, 3), v(j + 2 * set.len(), 0)],
                fv: [v(j + 2 * set.len(), 1), v(j + 2 * set.len(), 2), 0.5],
                r: [0.0; 3],
            })
            .collect();
        let basis: Vec<[f64; 3]> = (0..set.len()).map(|j| [v(j, 1), 0.3, v(j, 2)]).collect();
        let range = 0..set.len();
        for basis in [None, Some(basis)] {
            for masking in [Masking::Separable, Masking::HeightCorrelated] {
                let g = GramInput {
                    set: &set,
                    cache: &cache,
                    basis: &basis,
                    masking,
                };
                let bits = |a: [f64; crate::solver::gram::SIZE]| a.map(f64::to_bits);
                // SAFETY (each call): AVX2 was detected.
                let want = scalar::<1>(g, range.clone());
                assert_eq!(
                    bits(unsafe { gram_sums::<1>(g, range.clone()) }),
                    bits(want)
                );
                let want = scalar::<2>(g, range.clone());
                assert_eq!(
                    bits(unsafe { gram_sums::<2>(g, range.clone()) }),
                    bits(want)
                );
                let want = scalar::<3>(g, range.clone());
                assert_eq!(
                    bits(unsafe { gram_sums::<3>(g, range.clone()) }),
                    bits(want)
                );
                assert!(want.iter().any(|&x| x != 0.0));
            }
        }
    }
}
