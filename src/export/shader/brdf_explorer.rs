//! A Disney BRDF Explorer `analytic` file: parameters (an exposure in
//! stops, a switch for the diffuse term and one per lobe) and a shader
//! section defining `vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)`.
//! BRDF Explorer drops every line starting with `#` and declares the
//! parameters as uniforms itself; its templates already use `exposure`,
//! so every name here carries the prefix.

use super::emit::{Dialect, Source};
use super::glsl::{banner, eval_function};
use super::prepare::{prepare, ShaderError, ShaderOptions};
use crate::model::Model;

/// The model as a BRDF Explorer `.brdf` file. `BRDF` returns f (no cosine)
/// per channel, scaled by 2^`P_exposure`; `P_diffuse` and `P_lobeM`
/// switch terms off. X and Y (tangent, bitangent) fix phi for an
/// anisotropic model.
pub fn brdf_explorer_with(model: &Model, options: &ShaderOptions) -> Result<String, ShaderError> {
    let tables = prepare(model, options)?;
    let p = &options.prefix;
    let src = Source::new(model, &tables, Dialect::Glsl, p);
    let mut s = String::from("analytic\n\n::begin parameters\n");
    s += &format!("float {p}_exposure -8.0 8.0 0.0\nbool {p}_diffuse 1\n");
    for m in 0..model.lobe_count() {
        s += &format!("bool {p}_lobe{m} 1\n");
    }
    s += "::end parameters\n\n::begin shader\n";
    s += &banner(model, "BRDF Explorer shader of an npf fit");
    s += &src.tables(false);
    s += &src.helpers();
    s += &src.lookups();
    let diffuse_on = format!("{p}_diffuse");
    let lobe_on = |m: usize| format!("{p}_lobe{m}");
    s += &eval_function(&src, Some(&diffuse_on), Some(&lobe_on));
    s += &src.fill(
        "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) {
    vec3 wi = normalize(vec3(dot(L, X), dot(L, Y), dot(L, N)));
    vec3 wo = normalize(vec3(dot(V, X), dot(V, Y), dot(V, N)));
    return @eval(wo, wi) * exp2(@exposure);
}
",
    );
    s += "::end shader\n";
    debug_assert!(s.lines().all(|l| !l.trim_start().starts_with('#')));
    Ok(s)
}
