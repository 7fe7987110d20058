//! Energy compensation (Kelemen 2001, Kulla–Conty 2017, as in the seed
//! `001`): directional-albedo tables E(μ, α) for GGX and Oren–Nayar, the
//! average E_avg(α) and its polynomial fits, the multiple-scattering lobe
//! f_ms with its white-furnace check, the seed's reflectance factors, and a
//! microsurface random-walk simulator to refit the seed's τ.
//! Conventions and measured results: `docs/energy.md`.

/// Directional albedo tables E(mu, alpha) and their averages.
pub mod albedo;
/// The multiple-scattering lobe and the white-furnace check.
pub mod compensation;
/// A fitted model's specular albedo, for the energy-coupled diffuse form.
pub mod coupled;
/// Polynomial fits of E_avg(alpha).
pub mod fit;
/// GGX and Beckmann distributions and Smith terms in projected-area form.
pub mod microfacet;
pub mod quad;
/// A fitted model's energy against its table's (the post-fit scale).
pub mod scale;
/// The seed's reflectance series and constants.
pub mod series;
/// A microsurface random-walk simulator.
pub mod simulate;
/// Refitting the seed's tau from simulations.
pub mod tau;

pub use albedo::{AlbedoTable, Model};
pub use microfacet::{Masking, Ndf};
