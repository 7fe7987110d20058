//! The batch interface of [`NpfBxdf`]: `eval`, `sample` and `pdf` over
//! slices, structure of arrays in and out (what wavefront renderers,
//! packet tracers and the Python binding hold). Each entry is exactly the
//! per-call result (bit for bit, tested); the batch forms are faster
//! because [`FlatEval`](super::FlatEval) evaluates four pairs at once,
//! their dependency chains interleaved (see docs/sampling.md, "Batch
//! interface").

use super::{BsdfError, BsdfSample, Component, NpfBxdf};
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

    fn clear(&mut self) {
        let SampleBatch {
            wi,
            f,
            pdf,
            weight,
            component,
        } = self;
        for v in wi.iter_mut().chain(f.iter_mut()).chain(weight.iter_mut()) {
            v.clear();
        }
        pdf.clear();
        component.clear();
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
    /// `out` (cleared first): exactly the per-call draws. The draws are
    /// made one by one, their values four at a time by the flat
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
        out.clear();
        // (u_lobe, [u0, u1]) of draw j, in order.
        let us = u[0].iter().zip(u[1].iter().zip(u[2])).enumerate();
        let Some(flat) = self.flat() else {
            for (j, (&uc, (&u0, &u1))) in us {
                out.push(self.sample(wo.get(j), uc, [u0, u1]));
            }
            return Ok(());
        };
        for (j, (&uc, (&u0, &u1))) in us {
            let s = match self.draw(wo.get(j), uc, [u0, u1]) {
                // The value comes below; pdf and wi as drawn for now.
                Ok((wi, pdf, component)) => BsdfSample {
                    wi,
                    f: [0.0; 3],
                    pdf,
                    weight: [0.0; 3],
                    component,
                },
                Err(lost) => lost,
            };
            out.push(s);
        }
        let SampleBatch {
            wi,
            f,
            pdf,
            weight,
            component,
        } = out;
        let [f0, f1, f2] = f;
        flat.eval_slices(wo.slices(), [&wi[0], &wi[1], &wi[2]], [f0, f1, f2]);
        for j in 0..n {
            if !(pdf[j] > 0.0) {
                // Lost: zero value, as the per-call sample reports it.
                (0..3).for_each(|c| f[c][j] = 0.0);
                continue;
            }
            // BsdfSample::new's weight and checks.
            let w = [wi[0][j], wi[1][j], wi[2][j]];
            let s = BsdfSample::new(w, [f[0][j], f[1][j], f[2][j]], pdf[j], component[j]);
            pdf[j] = s.pdf;
            for c in 0..3 {
                f[c][j] = s.f[c];
                weight[c][j] = s.weight[c];
            }
        }
        Ok(())
    }
}
