//! An RGL `.bsdf` file's BRDF ([`RglBrdf`]) as a [`Bsdf`], in RGB
//! ([`RglBrdf::rgb`]: spectral files by `npf_data_loaders::spectrum`'s
//! route). The file's conditioning direction is the view (Mitsuba's
//! `si.wi`, pbrt's `wo`), so `eval(wo, wi)` asks the file at (wi = wo,
//! wo = wi) in its own names. The file's own importance sampling is not
//! used here: draws are cosine-weighted, with their exact density.

use super::{cosine_draw, cosine_pdf_for, Bsdf, BsdfSample};
use npf_data_loaders::geometry::Vec3;
use npf_data_loaders::rgl_brdf::RglBrdf;

impl Bsdf for RglBrdf {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        self.rgb(wo, wi)
    }

    fn sample(&self, wo: Vec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        cosine_draw(self, wo, u)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        cosine_pdf_for(wo, wi)
    }
}
