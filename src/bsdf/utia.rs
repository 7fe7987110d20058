//! A measured UTIA table as a [`Bsdf`]: the quadrilinear interpolation of
//! UTIA's own reader ([`UtiaTable::interpolate`]), zero below the horizon,
//! drawn by cosine-weighted hemisphere sampling. Directions are in the
//! table's frame: its phi = 0 is the shading frame's +x (the tangent).

use super::{cosine_draw, cosine_pdf_for, Bsdf, BsdfSample};
use npf_data_loaders::geometry::{angles_of, Vec3};
use npf_data_loaders::UtiaTable;

impl Bsdf for UtiaTable {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if !(wi[2] > 0.0 && wo[2] > 0.0) {
            return [0.0; 3];
        }
        let (ti, pi) = angles_of(wi);
        let (tv, pv) = angles_of(wo);
        self.interpolate(ti, pi, tv, pv)
    }

    fn sample(&self, wo: Vec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        cosine_draw(self, wo, u)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        cosine_pdf_for(wo, wi)
    }
}
