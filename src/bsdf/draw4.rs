//! Four draws at once ([`NpfBxdf::draw4`]) in lane types: the same
//! operations as [`NpfBxdf::draw`], bit for bit (tested), for the batch
//! sampler.

use super::azimuth::{azimuth_centre, turn_sin_cos_lanes, EDGE_COS};
use super::draw_geometry::*;
use super::factor::*;
use super::flat::acos_lanes;
use super::hemisphere::{cosine_direction, unit};
use super::interface::Component;
use super::lanes::Lanes4;
use npf_data_loaders::geometry::Vec3;
use std::f64::consts::PI;

/// The lobe densities of four draws' cells (lane k of each row for draw
/// k): per lobe m < SEL_ROW - 1, its share x density and its density (0
/// in lanes without a lobe part).
#[derive(Clone, Copy, Debug)]
pub(super) struct Dens4 {
    pub(super) share_d: [[f64; 4]; SEL_ROW - 1],
    pub(super) d: [[f64; 4]; SEL_ROW - 1],
}

impl NpfBxdf {
    /// [`NpfBxdf::draw`] of four views at once, exactly its results (bit
    /// for bit, tested), lane k of each array for draw k, a lost draw with
    /// pdf 0 and the direction and component `draw` reports: the view
    /// arccosines, each lobe draw's reflection and Jacobian and each
    /// diffuse draw's cosine direction and half vector in four lanes `V`
    /// (the square roots, the azimuth polynomials, the frame's division),
    /// the four draws' component choices, table searches and density reads
    /// one by one (independent, so the core overlaps them), then every
    /// draw's mixture pdf in the same lanes. Every lane sees the operations
    /// of `draw` in its order. The results go straight to arrays (no
    /// `Drawn` per lane: moving those enums cost about 50 instructions a
    /// draw).
    // No closures around lane operations (see `FlatEval::eval4`).
    #[inline(always)]
    pub(crate) fn draw4<V: Lanes4>(
        &self,
        wo: [Vec3; 4],
        u_lobe: [f64; 4],
        u: [[f64; 2]; 4],
    ) -> Drawn4 {
        let mut cos = [0.0; 4];
        for k in 0..4 {
            cos[k] = wo[k][2].clamp(0.0, 1.0);
        }
        let theta = acos_lanes(V::load(&cos)).to_array();
        let mut out = Drawn4 {
            wi: [[0.0; 4], [0.0; 4], [1.0; 4]],
            pdf: [0.0; 4],
            component: [Component::Diffuse; 4],
            theta_o: theta,
        };
        // Lanes of other draws get a harmless lobe draw, then discarded.
        let (mut t, mut sign, mut dv) = ([0.0; 4], [1.0; 4], [0.5; 4]);
        let (mut sc, mut cc) = ([0.0; 4], [1.0; 4]);
        let mut sels = [Sel {
            at: (0, 0.0),
            p: [0.0; SEL_ROW],
        }; 4];
        // The t and azimuth cells of each lobe draw (None: no lobe draw).
        let mut cells = [None; 4];
        // The mixture pdf in lanes: per lane, the diffuse share, each
        // lobe's share times its density in the cell of the draw's half
        // vector, and that density (a zero adds nothing). Only up to
        // SEL_ROW - 1 lobes (every model with a flat evaluator); others
        // take the per-lane `finish_lobe` and `diffuse_draw`.
        let nl = self.model.lobes.len();
        let in_lanes = nl < SEL_ROW;
        let mut p_diffuse = [0.0; 4];
        // 1 in the lanes of lobe draws, of diffuse draws made in lanes.
        let (mut lobe, mut diffuse) = ([0.0; 4], [0.0; 4]);
        // The diffuse draws' random numbers, `unit` as `cosine_hemisphere`'s.
        let mut ud = [[0.0; 4]; 2];
        let mut dens = Dens4 {
            share_d: [[0.0; 4]; SEL_ROW - 1],
            d: [[0.0; 4]; SEL_ROW - 1],
        };
        for k in 0..4 {
            sels[k] = self.selection_row_at(row_at_angle(theta[k]));
            if !(wo[k][2] > 0.0) {
                continue;
            }
            let Some(c) = self.choose(&sels[k], u_lobe[k]) else {
                continue;
            };
            p_diffuse[k] = sels[k].p[0];
            if c == 0 {
                if in_lanes {
                    diffuse[k] = 1.0;
                    (ud[0][k], ud[1][k]) = (unit(u[k][0]), unit(u[k][1]));
                    continue;
                }
                let (wi, pdf) = match self.diffuse_draw(wo[k], &sels[k], u[k]) {
                    Ok((wi, pdf, _)) => (wi, pdf),
                    Err(lost) => (lost.wi, 0.0),
                };
                (out.wi[0][k], out.wi[1][k], out.wi[2][k]) = (wi[0], wi[1], wi[2]);
                out.pdf[k] = pdf;
                continue;
            }
            let (cell, tk, d, s) = self.lobe_cells(&sels[k], c - 1, u[k]);
            out.component[k] = Component::Lobe(c - 1);
            cells[k] = Some(cell);
            [sc[k], cc[k]] = azimuth_centre(cell.1);
            (t[k], sign[k], dv[k]) = (tk, s, d);
            lobe[k] = 1.0;
            if in_lanes {
                self.read_densities(&mut dens, k, &sels[k], cell);
            }
        }
        let column = |c: usize| [wo[0][c], wo[1][c], wo[2][c], wo[3][c]];
        let (o0, o1, o2) = (column(0), column(1), column(2));
        let wo_l = [V::load(&o0), V::load(&o1), V::load(&o2)];
        let ex = frame_lanes(wo_l);
        let r = reflection_in::<V>(
            wo_l,
            ex,
            V::load(&t),
            V::load(&sign),
            [V::load(&sc), V::load(&cc)],
            V::load(&dv),
        );
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        let (s_z, wo_s, r2) = (r.jac.s_z, r.jac.wo_s, r.jac.r2);
        let jac_ok = zero.lt_select(
            s_z,
            zero.lt_select(wo_s, r2.lt_select(r2 + s_z * s_z, one, zero), zero),
            zero,
        );
        let kept = zero.lt_select(r.wo_h, zero.lt_select(r.wi[2], one, zero), zero);
        // Per lane: the draw's wi and Jacobian, 1 where it stands (a lobe
        // draw kept with a valid Jacobian, a diffuse draw above the
        // horizon), 1 where there is a draw in lanes at all.
        let (mut wi, mut jac, mut ok) = (r.wi, r.jac.jac, kept * jac_ok);
        let mut drawn = V::load(&lobe);
        if diffuse != [0.0; 4] {
            let is_diffuse = V::load(&diffuse);
            let (wd, jd) = self.diffuse_lanes::<V>(wo_l, ex, &diffuse, ud, &sels, &mut dens);
            for c in 0..3 {
                wi[c] = zero.lt_select(is_diffuse, wd[c], wi[c]);
            }
            jac = zero.lt_select(is_diffuse, jd, jac);
            ok = zero.lt_select(is_diffuse, zero.lt_select(wd[2], one, zero), ok);
            drawn = drawn + is_diffuse;
        }
        // `finish_lobe`'s and `pdf_at`'s operations in their order: the
        // diffuse part, each lobe's (share x density) x Jacobian where the
        // density is above 0, then 0 for a lost draw (see `ok`) or a pdf
        // not above 0.
        let p0 = V::load(&p_diffuse);
        let mut pdf = zero.lt_select(p0, p0 * wi[2] / V::splat(PI), zero);
        for m in 0..nl.min(SEL_ROW - 1) {
            let d = V::load(&dens.d[m]);
            pdf = pdf + zero.lt_select(d, V::load(&dens.share_d[m]) * jac, zero);
        }
        let pdf = zero.lt_select(pdf, pdf, zero);
        let pdf = zero.lt_select(ok, pdf, zero);
        let [w0, w1, w2] = wi;
        out.wi = [
            zero.lt_select(drawn, w0, V::load(&out.wi[0])).to_array(),
            zero.lt_select(drawn, w1, V::load(&out.wi[1])).to_array(),
            zero.lt_select(drawn, w2, V::load(&out.wi[2])).to_array(),
        ];
        out.pdf = zero.lt_select(drawn, pdf, V::load(&out.pdf)).to_array();
        // Rare: a kept lobe draw whose Jacobian `finish_lobe` would not
        // take (it then calls `pdf_at`), or more lobes than the lanes hold.
        let is_lobe = V::load(&lobe);
        let odd = (is_lobe * kept * (one - jac_ok)).to_array();
        if in_lanes && odd == [0.0; 4] {
            return out;
        }
        for k in 0..4 {
            let (Some(cell), Component::Lobe(m)) = (cells[k], out.component[k]) else {
                continue;
            };
            if in_lanes && odd[k] == 0.0 {
                continue;
            }
            let r = Reflection {
                wi: [out.wi[0][k], out.wi[1][k], out.wi[2][k]],
                wo_h: r.wo_h.to_array()[k],
                jac: JacobianParts {
                    s_z: s_z.to_array()[k],
                    wo_s: wo_s.to_array()[k],
                    r2: r2.to_array()[k],
                    jac: r.jac.jac.to_array()[k],
                },
            };
            out.pdf[k] = match self.finish_lobe(wo[k], &sels[k], m, cell, &r) {
                Ok((_, pdf, _)) => pdf,
                Err(_) => 0.0,
            };
        }
        out
    }

    /// Lane k's share x density and density of each of the first SEL_ROW
    /// - 1 lobes in cell (i, j) of its view's tables, into `dens`.
    #[inline(always)]
    fn read_densities(&self, dens: &mut Dens4, k: usize, sel: &Sel, cell: (usize, usize)) {
        let row = self.density_row(sel, cell);
        for (m, &dm) in row.iter().enumerate().take(SEL_ROW - 1) {
            (dens.share_d[m][k], dens.d[m][k]) = (sel.p[m + 1] * dm, dm);
        }
    }

    /// The diffuse draws of `draw4` in lanes (the lanes where `diffuse` is
    /// 1; `ud` their random numbers in [0, 1]): `cosine_hemisphere`'s
    /// direction and `pdf_at`'s Jacobian, and, where a lobe could have
    /// drawn that direction (the Jacobian valid), the densities of the
    /// cell `pdf_at` finds for its half vector (the t cell from the guide
    /// table, the azimuth cell by `azimuth_cell`'s compares), into those
    /// lanes of `dens`. Returns (wi, Jacobian) lanes.
    #[inline(always)]
    fn diffuse_lanes<V: Lanes4>(
        &self,
        wo: [V; 3],
        [ex0, ex1]: [V; 2],
        diffuse: &[f64; 4],
        ud: [[f64; 4]; 2],
        sels: &[Sel; 4],
        dens: &mut Dens4,
    ) -> ([V; 3], V) {
        let (sp, cp) = turn_sin_cos_lanes(V::load(&ud[1]));
        let wi = cosine_direction(V::load(&ud[0]), sp, cp);
        let jp = jacobian_parts(wo, wi);
        if self.densities.is_empty() {
            return (wi, jp.jac);
        }
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        // `JacobianParts::valid`, and a diffuse lane.
        let (s_z, r2) = (jp.s_z, jp.r2);
        let n2 = r2 + s_z * s_z;
        let valid = zero.lt_select(
            s_z,
            zero.lt_select(jp.wo_s, r2.lt_select(n2, one, zero), zero),
            zero,
        );
        let valid = (valid * V::load(diffuse)).to_array();
        if valid == [0.0; 4] {
            return (wi, jp.jac);
        }
        // `half_vector`'s h (x and y) and t; |s|^2 = n2 as its dot forms it.
        let inv = one / n2.sqrt();
        let (h0, h1) = ((wi[0] + wo[0]) * inv, (wi[1] + wo[1]) * inv);
        let th = (r2 / n2).min(one);
        // `azimuth_cell`: x <= c r is "not c r < x" (all finite where the
        // Jacobian is valid); y only enters squared, so h1 ex.x - h0 ex.y
        // serves for h0 (-ex.y) + h1 ex.x (they differ at most in a zero's
        // sign).
        let x = h0 * ex0 + h1 * ex1;
        let y = h1 * ex0 - h0 * ex1;
        let r = (x * x + y * y).sqrt();
        let mut count = zero;
        for c in EDGE_COS {
            count = count + (V::splat(c) * r).lt_select(x, zero, one);
        }
        let j = zero.lt_select(r, count, zero).to_u32();
        // `t_cell`'s guide entry.
        let g = self.t_guide.len();
        let b = (th.sqrt().sqrt() * V::splat(g as f64))
            .floor_index()
            .min(V::splat((g - 1) as f64))
            .to_u32();
        let th = th.to_array();
        for k in 0..4 {
            if valid[k] == 0.0 {
                continue;
            }
            let i = self.t_cell_from(b[k] as usize, th[k]);
            self.read_densities(dens, k, &sels[k], (i, j[k] as usize));
        }
        (wi, jp.jac)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;
    use crate::synth::known_factor_model;

    /// draw4 in lane type V against draw, bit for bit, on views that
    /// include the normal, grazing and invalid ones and random numbers
    /// at and outside [0, 1].
    fn check_draw4<V: Lanes4>(b: &NpfBxdf) -> usize {
        let mut next = crate::bsdf::test_uniforms(0x9e37_79b9_7f4a_7c15u64);
        let odd = [0.0, 1.0, 1.0 - 1e-17, 0.5, f64::NAN, -0.25, 2.0];
        let (mut drawn, mut n) = (0, 0);
        while n < 20_000 {
            let mut wo = [[0.0; 3]; 4];
            let (mut ul, mut u) = ([0.0; 4], [[0.0; 2]; 4]);
            for k in 0..4 {
                let z = match n % 97 {
                    0 => 1.0,
                    1 => 1e-9,
                    2 => -0.3,
                    3 => f64::NAN,
                    _ => next(),
                };
                let r = (1.0 - z * z).max(0.0).sqrt();
                let p = next() * std::f64::consts::TAU;
                wo[k] = [r * p.cos(), r * p.sin(), z];
                ul[k] = next();
                u[k] = [next(), next()];
                if n % 89 < 3 {
                    u[k][n % 2] = odd[n % odd.len()];
                    ul[k] = odd[(n / 2) % odd.len()];
                }
                n += 1;
            }
            let got = b.draw4::<V>(wo, ul, u);
            for k in 0..4 {
                let one = b.draw(wo[k], ul[k], u[k]);
                let (wi, pdf, c) = match one {
                    Ok(d) => d,
                    Err(l) => (l.wi, l.pdf, l.component),
                };
                let four = (
                    [got.wi[0][k], got.wi[1][k], got.wi[2][k]].map(f64::to_bits),
                    got.pdf[k].to_bits(),
                    got.component[k],
                );
                let one_bits = (wi.map(f64::to_bits), pdf.to_bits(), c);
                assert_eq!(four, one_bits, "{wo:?} {ul:?} {u:?} lane {k}");
                drawn += usize::from(one.is_ok());
            }
        }
        drawn
    }

    #[test]
    fn four_draws_at_once_equal_one_at_a_time_bit_for_bit() {
        let mut with_diffuse = known_factor_model(Layout::default(), &[0.02, 0.15, 0.5]);
        with_diffuse.diffuse = [0.2, 0.1, 0.05];
        // Mostly diffuse (a matte fabric): most groups of four hold
        // several diffuse draws, many all four.
        let mut matte = known_factor_model(Layout::default(), &[0.5]);
        matte.diffuse = [0.8, 0.7, 0.6];
        let mut max_diffuse = 0.0f64;
        for model in [
            with_diffuse,
            known_factor_model(Layout::isotropic(30), &[0.3]),
            matte,
        ] {
            let b = NpfBxdf::new(model).unwrap();
            max_diffuse = max_diffuse.max(b.selection_probabilities([0.0, 0.0, 1.0])[0]);
            // Not vacuous: most draws carry light.
            assert!(check_draw4::<crate::bsdf::lanes::F64x2x2>(&b) > 10_000);
            #[cfg(target_arch = "x86_64")]
            if is_x86_feature_detected!("avx2") {
                #[target_feature(enable = "avx2")]
                fn avx(b: &NpfBxdf) -> usize {
                    check_draw4::<crate::bsdf::lanes::avx::F64x4>(b)
                }
                // SAFETY: AVX2 was detected.
                assert!(unsafe { avx(&b) } > 10_000);
            }
        }
        // The matte model draws mostly diffuse.
        assert!(max_diffuse > 0.5, "{max_diffuse}");
    }
}
