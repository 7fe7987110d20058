//! The half-vector azimuth cells of the tabulated samplers and branch-free
//! (sin, cos) of an azimuth, scalar and in lanes (the same bits).

use super::f64x2::floor_index;
use super::lanes::{Lanes, Lanes4};
use npf_data_loaders::geometry::Vec3;
use std::f64::consts::PI;

/// Cells of the relative half-vector azimuth |phi_h - phi_o| in [0, pi] per
/// t cell of a lobe's view table (the lobe is mirror-symmetric about wo's
/// plane of incidence; the sign of the azimuth is drawn with probability 1/2).
pub const PHI_CELLS: usize = 8;

/// (sin, cos) of the centre (j + 1/2) pi / PHI_CELLS of azimuth cell j.
#[inline(always)]
pub(super) fn azimuth_centre(j: usize) -> [f64; 2] {
    const _: () = assert!(PHI_CELLS == 8, "CENTRE holds the centres of 8 cells");
    CENTRE[j.min(PHI_CELLS - 1)]
}

/// The cosines of the inner azimuth cell edges, cos(k pi / 8), k = 1..7.
pub(super) const EDGE_COS: [f64; PHI_CELLS - 1] = {
    const _: () = assert!(PHI_CELLS == 8, "EDGE_COS holds the edges of 8 cells");
    let c1 = 0.923_879_532_511_286_7;
    let c2 = std::f64::consts::FRAC_1_SQRT_2;
    let c3 = 0.382_683_432_365_089_8;
    [c1, c2, c3, 0.0, -c3, -c2, -c1]
};

/// The azimuth cell of a half vector, `floor(|phi_h - phi_o| / pi *
/// PHI_CELLS)`, by comparing cos(phi) with the cell edges' cosines (no
/// atan2): phi >= k pi / PHI_CELLS iff x <= cos(k pi / PHI_CELLS) r.
#[inline]
pub(super) fn azimuth_cell(h: Vec3, ex: [f64; 2], ey: [f64; 2]) -> usize {
    let x = h[0] * ex[0] + h[1] * ex[1];
    let y = h[0] * ey[0] + h[1] * ey[1];
    let r = (x * x + y * y).sqrt();
    if !(r > 0.0) {
        return 0;
    }
    EDGE_COS.iter().filter(|&&c| x <= c * r).count()
}

/// (sin, cos) of the centres (j + 1/2) pi / 8 of the eight cells of pi / 8
/// in [0, pi].
pub(super) const CENTRE: [[f64; 2]; 8] = {
    let (s1, c1) = (0.195_090_322_016_128_26, 0.980_785_280_403_230_4);
    let (s3, c3) = (0.555_570_233_019_602_2, 0.831_469_612_302_545_2);
    [
        [s1, c1],
        [s3, c3],
        [c3, s3],
        [c1, s1],
        [c1, -s1],
        [c3, -s3],
        [s3, -c3],
        [s1, -c1],
    ]
};

/// Cells of pi / 8 in a whole turn (`turn_sin_cos`).
pub(super) const TURN_CELLS: usize = 16;

/// (sin, cos) of the centres (j + 1/2) pi / 8 of the sixteen cells of a
/// turn: CENTRE, then CENTRE negated (an angle plus pi, exactly).
pub(super) const TURN_CENTRE: [[f64; 2]; TURN_CELLS] = {
    let mut t = [[0.0; 2]; TURN_CELLS];
    let mut j = 0;
    while j < 8 {
        t[j] = CENTRE[j];
        t[j + 8] = [-CENTRE[j][0], -CENTRE[j][1]];
        j += 1;
    }
    t
};

/// (sin, cos) of the angle 2 pi u for u in [0, 1] (the cosine draw's
/// azimuth): the turn in sixteen cells of pi / 8 (16 u is exact, its
/// floor the cell j, the rest dv), the cell's centre rotated by
/// `azimuth_sin_cos`' polynomials. Within 1e-15 of libm's `sin_cos`
/// (tested), without its branches, and in lanes too
/// (`turn_sin_cos_lanes`, the same bits).
#[inline(always)]
pub(super) fn turn_sin_cos(u: f64) -> (f64, f64) {
    let x = u * TURN_CELLS as f64;
    let j = floor_index(x).min(TURN_CELLS - 1);
    azimuth_sin_cos::<f64>(TURN_CENTRE[j], x - j as f64)
}

/// [`turn_sin_cos`] of four u in [0, 1] at once (the same operations).
#[inline(always)]
pub(super) fn turn_sin_cos_lanes<V: Lanes4>(u: V) -> (V, V) {
    let x = u * V::splat(TURN_CELLS as f64);
    let j = x.floor_index().min(V::splat((TURN_CELLS - 1) as f64));
    let js = j.to_u32();
    // Written out: `[..].map(..)` compiles to out-of-line calls in lanes code.
    let c = [
        TURN_CENTRE[(js[0] as usize).min(TURN_CELLS - 1)],
        TURN_CENTRE[(js[1] as usize).min(TURN_CELLS - 1)],
        TURN_CENTRE[(js[2] as usize).min(TURN_CELLS - 1)],
        TURN_CENTRE[(js[3] as usize).min(TURN_CELLS - 1)],
    ];
    let sc = V::load(&[c[0][0], c[1][0], c[2][0], c[3][0]]);
    let cc = V::load(&[c[0][1], c[1][1], c[2][1], c[3][1]]);
    azimuth_sin_cos([sc, cc], x - j)
}

/// (sin, cos) of the azimuth (j + dv) pi / PHI_CELLS, dv in [0, 1], lane
/// by lane: the cell centre's `[sc, cc]` (from `azimuth_centre`) rotated
/// by a = (dv - 1/2) pi / PHI_CELLS, |a| <= pi / 16, whose sine and cosine
/// are Taylor polynomials with remainders below 1e-18 (tested against
/// `f64::sin_cos`).
#[inline(always)]
pub(super) fn azimuth_sin_cos<V: Lanes>([sc, cc]: [V; 2], dv: V) -> (V, V) {
    // Taylor coefficients (-1)^k / (2k+1)! and (-1)^k / (2k)!.
    const S: [f64; 5] = [
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
    ];
    const C: [f64; 6] = [
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
    ];
    let c = V::splat;
    let a = (dv - c(0.5)) * c(PI / PHI_CELLS as f64);
    let a2 = a * a;
    let sin_a =
        a + a * a2 * (c(S[0]) + a2 * (c(S[1]) + a2 * (c(S[2]) + a2 * (c(S[3]) + a2 * c(S[4])))));
    let cos_a = c(1.0)
        + a2 * (c(C[0])
            + a2 * (c(C[1]) + a2 * (c(C[2]) + a2 * (c(C[3]) + a2 * (c(C[4]) + a2 * c(C[5]))))));
    (sc * cos_a + cc * sin_a, cc * cos_a - sc * sin_a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn azimuth_sin_cos_is_the_library_s() {
        let mut worst = 0.0f64;
        for j in 0..PHI_CELLS {
            for k in 0..=1000 {
                let dv = k as f64 / 1000.0;
                let (s, c) = azimuth_sin_cos::<f64>(azimuth_centre(j), dv);
                let (s0, c0) = ((j as f64 + dv) * PI / PHI_CELLS as f64).sin_cos();
                worst = worst.max((s - s0).abs()).max((c - c0).abs());
            }
        }
        // Within a few ulps of 1 (both sides round).
        assert!(worst <= 1e-15, "worst {worst:e}");
    }

    /// turn_sin_cos_lanes in lane type V: turn_sin_cos's bits, lane by lane.
    fn check_turn_lanes<V: Lanes4>(us: &[f64]) {
        for q in us.chunks_exact(4) {
            let q = [q[0], q[1], q[2], q[3]];
            let (s, c) = turn_sin_cos_lanes(V::load(&q));
            let (s, c) = (s.to_array(), c.to_array());
            for k in 0..4 {
                let (s1, c1) = turn_sin_cos(q[k]);
                assert_eq!(
                    (s[k].to_bits(), c[k].to_bits()),
                    (s1.to_bits(), c1.to_bits())
                );
            }
        }
    }

    #[test]
    fn turn_sin_cos_is_the_library_s() {
        // Every 1/16 cell edge (k a multiple of n / 16), both ends and
        // points between.
        let n = 160_000;
        let us: Vec<f64> = (0..=n)
            .flat_map(|k| [k as f64 / n as f64, (k as f64 + 0.37) / n as f64])
            .filter(|&u| u <= 1.0)
            .chain([1.0 - 1e-17, 1.0 - f64::EPSILON, 1e-300, 0.0])
            .collect();
        let mut worst = 0.0f64;
        for &u in &us {
            let (s, c) = turn_sin_cos(u);
            let (s0, c0) = (2.0 * PI * u).sin_cos();
            worst = worst.max((s - s0).abs()).max((c - c0).abs());
        }
        // A few ulps of 1 (libm's argument 2 pi u is itself rounded).
        assert!(worst <= 1e-15, "worst {worst:e}");
        check_turn_lanes::<crate::bsdf::lanes::F64x2x2>(&us);
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            #[target_feature(enable = "avx2")]
            fn avx(us: &[f64]) {
                check_turn_lanes::<crate::bsdf::lanes::avx::F64x4>(us)
            }
            // SAFETY: AVX2 was detected.
            unsafe { avx(&us) };
        }
    }
}
