//! The benchmark's configurations: which models and fit options the report
//! compares, in report order.

use crate::fit::{FitConfig, ModelKind};
use crate::model::Masking;
use crate::samples::Weighting;
use crate::solver::{DiffuseKind, GMethod};

/// One fitted configuration of the benchmark.
#[derive(Clone, Debug)]
pub struct Configuration {
    /// Short name (file names, `--configs`).
    pub name: &'static str,
    /// One-line description for the report.
    pub what: &'static str,
    /// Which model it fits.
    pub kind: ModelKind,
    /// Specular lobes (factor model).
    pub lobes: usize,
    /// How G is updated.
    pub g_method: GMethod,
    /// Residual weighting.
    pub weighting: Weighting,
    /// The accuracy options (diffuse form, masking, grazing fit,
    /// compensation) applied on top of the defaults.
    pub options: fn(FitConfig) -> FitConfig,
}

/// All benchmark configurations, in report order.
pub fn configurations() -> Vec<Configuration> {
    let c = |name, what, kind, lobes, g_method, weighting| Configuration {
        name,
        what,
        kind,
        lobes,
        g_method,
        weighting,
        options: |f| f,
    };
    // The accuracy options of issue 16, each on the default sf-3.
    let option = |name, what, options: fn(FitConfig) -> FitConfig| Configuration {
        options,
        ..c(name, what, Factor, 3, Cubic, Compressive)
    };
    use GMethod::*;
    use ModelKind::*;
    use Weighting::*;
    vec![
        c(
            "sf-3",
            "shared-factor, 3 lobes, cubic G, compressive weights (npf's default)",
            Factor,
            3,
            Cubic,
            Compressive,
        ),
        c(
            "sf-2",
            "shared-factor, 2 lobes",
            Factor,
            2,
            Cubic,
            Compressive,
        ),
        c(
            "sf-1",
            "shared-factor, 1 lobe",
            Factor,
            1,
            Cubic,
            Compressive,
        ),
        c(
            "sf-3-golden",
            "3 lobes, G by golden-section search",
            Factor,
            3,
            Golden,
            Compressive,
        ),
        c(
            "sf-3-fixed-g",
            "3 lobes, G left at its initial Smith shape",
            Factor,
            3,
            Fixed,
            Compressive,
        ),
        c(
            "sf-3-cosine-l2",
            "3 lobes, cosine-weighted L2 weights",
            Factor,
            3,
            Cubic,
            CosineL2,
        ),
        c(
            "sf-3-uniform",
            "3 lobes, uniform weights",
            Factor,
            3,
            Cubic,
            Uniform,
        ),
        option(
            "sf-3-energy-coupled",
            "3 lobes, energy-coupled diffuse term",
            |f| FitConfig {
                diffuse: DiffuseKind::EnergyCoupled,
                ..f
            },
        ),
        option("sf-3-oren-nayar", "3 lobes, Oren-Nayar diffuse term", |f| {
            FitConfig {
                diffuse: DiffuseKind::OrenNayar,
                ..f
            }
        }),
        option("sf-3-g2", "3 lobes, height-correlated masking G2", |f| {
            FitConfig {
                masking: Masking::HeightCorrelated,
                ..f
            }
        }),
        option(
            "sf-3-taper",
            "3 lobes, fitted to 89 deg with weights tapering from 80 deg",
            |f| FitConfig {
                max_theta: 89.0,
                taper_from: Some(80.0),
                ..f
            },
        ),
        option(
            "sf-3-compensated",
            "3 lobes plus Kulla-Conty multiple scattering of the fitted lobes",
            |f| FitConfig {
                compensate: true,
                ..f
            },
        ),
        c(
            "independent-g",
            "Bagher et al.'s Independent-G (per-channel D, F, G; golden-section G)",
            IndependentG,
            1,
            Golden,
            Compressive,
        ),
        c(
            "ggx",
            "analytic GGX + Lambert, Schlick F (10 parameters)",
            Ggx,
            1,
            Cubic,
            Compressive,
        ),
    ]
}

impl Configuration {
    /// The fit configuration: the library's defaults with this
    /// configuration's choices, one thread (the report runs jobs side by
    /// side), and an optional sweep limit.
    pub fn fit_config(&self, max_sweeps: Option<usize>) -> FitConfig {
        let defaults = FitConfig::default();
        (self.options)(FitConfig {
            model: self.kind,
            lobes: self.lobes,
            g_method: self.g_method,
            weighting: self.weighting,
            threads: 1,
            max_sweeps: max_sweeps.unwrap_or(defaults.max_sweeps),
            ..defaults
        })
    }

    /// The model's parameter count.
    pub fn params(&self) -> usize {
        self.fit_config(None).effective_params()
    }
}
