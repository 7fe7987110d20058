//! The batch interface of [`NpfBxdf`]: `eval`, `sample` and `pdf` over
//! slices, structure of arrays in and out (what wavefront renderers,
//! packet tracers and the Python binding hold). Each entry is exactly the
//! per-call result (bit for bit, tested); the batch forms are faster
//! because [`FlatEval`](super::FlatEval) evaluates four pairs at once,
//! their dependency chains interleaved (see docs/sampling.md, "Batch
//! interface").

use super::lanes::{F64x2x2, Lanes4};
use super::{BsdfError, BsdfSample, Component, FlatEval, NpfBxdf};
use npf_data_loaders::geometry::Vec3;

/// Directions as a structure of arrays: component k of direction j is
/// `x[j]`, `y[j]`, `z[j]` (local shading frame, unit length).
#[derive(Clone, Copy, Debug)]
pub struct Directions<'a> {
    /// x components.
    pub x: &'a [f64],
    /// y components.
    pub y: &'a [f64],
    /// z components (along the normal).
    pub z: &'a [f64],
}

impl<'a> Directions<'a> {
    /// Directions from three component slices of one length.
    pub fn new(x: &'a [f64], y: &'a [f64], z: &'a [f64]) -> Result<Self, BsdfError> {
        let d = Directions { x, y, z };
        d.checked_len("directions")?;
        Ok(d)
    }

    /// Number of directions (the length of `x`).
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Direction j (j < len and the slices of one length).
    #[inline(always)]
    pub fn get(&self, j: usize) -> Vec3 {
        [self.x[j], self.y[j], self.z[j]]
    }

    /// The three slices.
    fn slices(&self) -> [&'a [f64]; 3] {
        [self.x, self.y, self.z]
    }

    /// The common length, or an error naming `what` when y or z differ.
    fn checked_len(&self, what: &'static str) -> Result<usize, BsdfError> {
        let n = self.x.len();
        for found in [self.y.len(), self.z.len()] {
            same_len(what, n, found)?;
        }
        Ok(n)
    }
}

fn same_len(what: &'static str, expected: usize, found: usize) -> Result<(), BsdfError> {
    if expected == found {
        Ok(())
    } else {
        Err(BsdfError::BatchLength {
            what,
            expected,
            found,
        })
    }
}

/// Draws of [`NpfBxdf::sample_batch`], a structure of arrays: entry j is
/// draw j's [`BsdfSample`] fields (lost draws have pdf 0 and zero f and
/// weight, as [`NpfBxdf::sample`] reports them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SampleBatch {
    /// Incident directions: x, y, z.
    pub wi: [Vec<f64>; 3],
    /// BRDF values per channel.
    pub f: [Vec<f64>; 3],
    /// Densities per solid angle (0 for a lost draw).
    pub pdf: Vec<f64>,
    /// Monte Carlo weights f cos theta_i / pdf per channel.
    pub weight: [Vec<f64>; 3],
    /// The component that drew each wi.
    pub component: Vec<Component>,
}

impl SampleBatch {
    /// Number of draws held.
    pub fn len(&self) -> usize {
        self.pdf.len()
    }

    /// True when it holds none.
    pub fn is_empty(&self) -> bool {
        self.pdf.is_empty()
    }

    /// Draw j as a [`BsdfSample`].
    pub fn get(&self, j: usize) -> BsdfSample {
        BsdfSample {
            wi: [self.wi[0][j], self.wi[1][j], self.wi[2][j]],
            f: [self.f[0][j], self.f[1][j], self.f[2][j]],
            pdf: self.pdf[j],
            weight: [self.weight[0][j], self.weight[1][j], self.weight[2][j]],
            component: self.component[j],
        }
    }

    /// n entries, their old values kept (a pass writes every field before
    /// anything reads it); 0 clears.
    fn resize(&mut self, n: usize) {
        let SampleBatch {
            wi,
            f,
            pdf,
            weight,
            component,
        } = self;
        for v in wi.iter_mut().chain(f.iter_mut()).chain(weight.iter_mut()) {
            v.resize(n, 0.0);
        }
        pdf.resize(n, 0.0);
        component.resize(n, Component::Diffuse);
    }

    fn push(&mut self, s: BsdfSample) {
        for c in 0..3 {
            self.wi[c].push(s.wi[c]);
            self.f[c].push(s.f[c]);
            self.weight[c].push(s.weight[c]);
        }
        self.pdf.push(s.pdf);
        self.component.push(s.component);
    }
}

impl NpfBxdf {
    /// [`NpfBxdf::eval`] of every pair (wo[j], wi[j]) into `out[c][j]`
    /// (channel c), exactly the per-call values; four pairs at a time
    /// through the flat evaluator when the model has one. An error when
    /// the slices' lengths differ.
    pub fn eval_batch(
        &self,
        wo: Directions,
        wi: Directions,
        out: [&mut [f64]; 3],
    ) -> Result<(), BsdfError> {
        let n = wo.checked_len("wo")?;
        same_len("wi", n, wi.checked_len("wi")?)?;
        for o in &out {
            same_len("eval output", n, o.len())?;
        }
        match self.flat() {
            Some(f) => f.eval_slices(wo.slices(), wi.slices(), out),
            None => {
                let [o0, o1, o2] = out;
                for j in 0..n {
                    [o0[j], o1[j], o2[j]] = self.eval(wo.get(j), wi.get(j));
                }
            }
        }
        Ok(())
    }

    /// [`NpfBxdf::pdf`] of every pair into `out[j]` (per call: the pdf
    /// has no batch kernel yet). An error when the lengths differ.
    pub fn pdf_batch(
        &self,
        wo: Directions,
        wi: Directions,
        out: &mut [f64],
    ) -> Result<(), BsdfError> {
        let n = wo.checked_len("wo")?;
        same_len("wi", n, wi.checked_len("wi")?)?;
        same_len("pdf output", n, out.len())?;
        for (j, o) in out.iter_mut().enumerate() {
            *o = self.pdf(wo.get(j), wi.get(j));
        }
        Ok(())
    }

    /// [`NpfBxdf::sample`] for every view wo[j] with random numbers
    /// (u[0][j], [u[1][j], u[2][j]]) (component, then direction), into
    /// `out` (resized to wo's length): exactly the per-call draws. The
    /// draws are made four at a time ([`NpfBxdf::draw4`]: their
    /// arithmetic in lanes), their values four at a time by the flat
    /// evaluator. An error when the lengths differ.
    pub fn sample_batch(
        &self,
        wo: Directions,
        u: [&[f64]; 3],
        out: &mut SampleBatch,
    ) -> Result<(), BsdfError> {
        let n = wo.checked_len("wo")?;
        for v in u {
            same_len("random numbers", n, v.len())?;
        }
        // The batch draws weigh a Lambertian diffuse term only.
        let Some(flat) = self.flat().filter(|f| f.is_lambert()) else {
            out.resize(0);
            // (u_lobe, [u0, u1]) of draw j, in order.
            let us = u[0].iter().zip(u[1].iter().zip(u[2])).enumerate();
            for (j, (&uc, (&u0, &u1))) in us {
                out.push(self.sample(wo.get(j), uc, [u0, u1]));
            }
            return Ok(());
        };
        out.resize(n);
        self.sample_slices(flat, wo, u, out);
        Ok(())
    }
}

impl NpfBxdf {
    /// `sample_batch` for a model with a flat evaluator: the draws into
    /// `out` (already of wo's length) four at a time by
    /// [`NpfBxdf::draw4`], their values by the flat evaluator, then the
    /// weights in lanes: AVX2 lanes where the CPU has them (detected at
    /// run time), SSE2 pairs otherwise; the same results either way.
    fn sample_slices(
        &self,
        flat: &FlatEval,
        wo: Directions,
        u: [&[f64]; 3],
        out: &mut SampleBatch,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            #[target_feature(enable = "avx2")]
            fn run(
                b: &NpfBxdf,
                flat: &FlatEval,
                wo: Directions,
                u: [&[f64]; 3],
                out: &mut SampleBatch,
            ) {
                b.sample_slices_in::<super::lanes::avx::F64x4>(flat, wo, u, out)
            }
            // SAFETY: AVX2 was detected just above.
            return unsafe { run(self, flat, wo, u, out) };
        }
        self.sample_slices_in::<F64x2x2>(flat, wo, u, out)
    }

    /// Each group of four: the draws ([`NpfBxdf::draw4`]), their values
    /// ([`FlatEval::eval4_view`], given the draws' view angles) and the
    /// weights in lanes, straight into `out` (no pass over the slices in
    /// between: the group's wi, pdf and values stay in registers).
    #[inline(always)]
    fn sample_slices_in<V: Lanes4>(
        &self,
        flat: &FlatEval,
        wo: Directions,
        u: [&[f64]; 3],
        out: &mut SampleBatch,
    ) {
        let n = wo.len();
        // Every slice cut to n once (fewer bounds checks in the loop).
        let [x, y, z] = wo.slices();
        let (x, y, z) = (&x[..n], &y[..n], &z[..n]);
        let (u0, u1, u2) = (&u[0][..n], &u[1][..n], &u[2][..n]);
        let SampleBatch {
            wi,
            f,
            pdf,
            weight,
            component,
        } = out;
        let [o0, o1, o2] = wi.each_mut().map(|v| &mut v[..n]);
        let [f0, f1, f2] = f.each_mut().map(|v| &mut v[..n]);
        let [w0, w1, w2] = weight.each_mut().map(|v| &mut v[..n]);
        let (pdf, component) = (&mut pdf[..n], &mut component[..n]);
        let mut k = 0;
        while k < n {
            // The last group repeats its final draw in its unused slots.
            // Written out: `[..].map(..)` compiled to out-of-line calls here.
            let at = [
                k,
                (k + 1).min(n - 1),
                (k + 2).min(n - 1),
                (k + 3).min(n - 1),
            ];
            let wo4 = [
                [x[at[0]], y[at[0]], z[at[0]]],
                [x[at[1]], y[at[1]], z[at[1]]],
                [x[at[2]], y[at[2]], z[at[2]]],
                [x[at[3]], y[at[3]], z[at[3]]],
            ];
            let d = self.draw4::<V>(
                wo4,
                [u0[at[0]], u0[at[1]], u0[at[2]], u0[at[3]]],
                [
                    [u1[at[0]], u2[at[0]]],
                    [u1[at[1]], u2[at[1]]],
                    [u1[at[2]], u2[at[2]]],
                    [u1[at[3]], u2[at[3]]],
                ],
            );
            let wi4 = [
                [d.wi[0][0], d.wi[1][0], d.wi[2][0]],
                [d.wi[0][1], d.wi[1][1], d.wi[2][1]],
                [d.wi[0][2], d.wi[1][2], d.wi[2][2]],
                [d.wi[0][3], d.wi[1][3], d.wi[2][3]],
            ];
            let v = flat.eval4_view::<V>(wo4, wi4, Some(V::load(&d.theta_o)));
            // Lanes: BsdfSample::new's weight and test, in its order; a lost
            // draw (pdf 0) gets zero value and weight, as the per-call
            // sample reports it.
            let (p, zj) = (V::load(&d.pdf), V::load(&d.wi[2]));
            let q = zj / p;
            let fs = [
                V::load(&[v[0][0], v[1][0], v[2][0], v[3][0]]),
                V::load(&[v[0][1], v[1][1], v[2][1], v[3][1]]),
                V::load(&[v[0][2], v[1][2], v[2][2], v[3][2]]),
            ];
            let rows = [
                kept(p, zj, fs[0]).to_array(),
                kept(p, zj, fs[1]).to_array(),
                kept(p, zj, fs[2]).to_array(),
                kept(p, zj, fs[0] * q).to_array(),
                kept(p, zj, fs[1] * q).to_array(),
                kept(p, zj, fs[2] * q).to_array(),
                kept(p, zj, p).to_array(),
            ];
            if k + 4 <= n {
                // Fixed lengths: stores, not memcpy calls.
                let e = k + 4;
                o0[k..e].copy_from_slice(&d.wi[0]);
                o1[k..e].copy_from_slice(&d.wi[1]);
                o2[k..e].copy_from_slice(&d.wi[2]);
                f0[k..e].copy_from_slice(&rows[0]);
                f1[k..e].copy_from_slice(&rows[1]);
                f2[k..e].copy_from_slice(&rows[2]);
                w0[k..e].copy_from_slice(&rows[3]);
                w1[k..e].copy_from_slice(&rows[4]);
                w2[k..e].copy_from_slice(&rows[5]);
                pdf[k..e].copy_from_slice(&rows[6]);
                component[k..e].copy_from_slice(&d.component);
            } else {
                for j in 0..n - k {
                    (o0[k + j], o1[k + j], o2[k + j]) = (d.wi[0][j], d.wi[1][j], d.wi[2][j]);
                    (f0[k + j], f1[k + j], f2[k + j]) = (rows[0][j], rows[1][j], rows[2][j]);
                    (w0[k + j], w1[k + j], w2[k + j]) = (rows[3][j], rows[4][j], rows[5][j]);
                    (pdf[k + j], component[k + j]) = (rows[6][j], d.component[j]);
                }
            }
            k += 4;
        }
    }
}

/// `v` where a draw carries light (0 < pdf < infinity and 0 < wi.z, the
/// test of `BsdfSample::new`, NaN failing it), else 0, lane by lane.
#[inline(always)]
fn kept<V: Lanes4>(pdf: V, wi_z: V, v: V) -> V {
    let (zero, inf) = (V::splat(0.0), V::splat(f64::INFINITY));
    zero.lt_select(
        pdf,
        pdf.lt_select(inf, zero.lt_select(wi_z, v, zero), zero),
        zero,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;
    use crate::synth::known_factor_model;

    /// The batch sample in SSE2 pairs (the path of CPUs without AVX2; the
    /// public tests run AVX2 where the CPU has it) equals the per-call
    /// samples bit for bit, lost draws included.
    #[test]
    fn the_sse2_batch_sample_equals_the_per_call_samples() {
        let mut model = known_factor_model(Layout::default(), &[0.02, 0.15, 0.5]);
        model.diffuse = [0.2, 0.1, 0.05];
        let b = NpfBxdf::new(model).unwrap();
        let flat = b.flat().expect("a flat model");
        let n = 1023;
        let mut next = crate::bsdf::test_uniforms(0x2545_f491_4f6c_dd1du64);
        let mut wo: [Vec<f64>; 3] = Default::default();
        let mut u: [Vec<f64>; 3] = Default::default();
        for j in 0..n {
            // Views up to grazing and a few below the horizon.
            let z = if j % 50 == 0 { -0.2 } else { next() };
            let (r, p) = (
                (1.0 - z * z).max(0.0).sqrt(),
                next() * std::f64::consts::TAU,
            );
            for (c, v) in [r * p.cos(), r * p.sin(), z].into_iter().enumerate() {
                wo[c].push(v);
            }
            for v in &mut u {
                v.push(next());
            }
        }
        let d = Directions::new(&wo[0], &wo[1], &wo[2]).unwrap();
        let mut out = SampleBatch::default();
        out.resize(n);
        b.sample_slices_in::<F64x2x2>(flat, d, [&u[0], &u[1], &u[2]], &mut out);
        let mut lit = 0;
        for j in 0..n {
            let one = b.sample(d.get(j), u[0][j], [u[1][j], u[2][j]]);
            let got = out.get(j);
            let bits = |s: &BsdfSample| {
                let v: Vec<u64> = (s.wi.iter().chain(&s.f).chain(&s.weight))
                    .chain([&s.pdf])
                    .map(|x| x.to_bits())
                    .collect();
                (v, s.component)
            };
            assert_eq!(bits(&got), bits(&one), "draw {j}");
            lit += usize::from(!one.is_lost());
        }
        assert!(lit > n / 2, "{lit} of {n} carry light");
    }
}
