//! Energy compensation (Kelemen 2001, Kulla–Conty 2017, as in the seed
//! `001`): directional-albedo tables E(μ, α) for GGX and Oren–Nayar, the
//! average E_avg(α) and its polynomial fits, the multiple-scattering lobe
//! f_ms with its white-furnace check, the seed's reflectance factors, and a
//! microsurface random-walk simulator to refit the seed's τ.
//! Conventions and measured results: `docs/energy.md`.

pub mod albedo;
pub mod compensation;
pub mod fit;
pub mod microfacet;
pub mod quad;
pub mod series;
pub mod simulate;
pub mod tau;

pub use albedo::{AlbedoTable, Model};
pub use microfacet::{Masking, Ndf};
