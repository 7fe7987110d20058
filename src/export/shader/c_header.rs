//! A dependency-free C99 header of a model (only `<math.h>`): `@eval`,
//! `@pdf` and `@sample`, `static inline`, tables `static const float`,
//! arithmetic in double (so eval matches `Model::eval` to rounding).

use super::emit::{Dialect, Source};
use super::prepare::{prepare, ShaderError, ShaderOptions};
use crate::model::Model;

/// The model as a C99 header:
///
/// - `void P_eval(const double wo[3], const double wi[3], double f[3])`;
/// - `double P_pdf(const double wo[3], const double wi[3])`;
/// - `int P_sample(const double wo[3], double uc, const double u[2],
///   double wi[3], double f[3], double *pdf)`: 0 (pdf and f zero) when
///   the draw leaves the upper hemisphere.
pub fn c_header_with(model: &Model, options: &ShaderOptions) -> Result<String, ShaderError> {
    let tables = prepare(model, options)?;
    let src = Source::new(model, &tables, Dialect::C, &options.prefix);
    let guard = format!("{}_BRDF_H", options.prefix.to_ascii_uppercase());
    let banner = super::glsl::banner(model, "C99 header of an npf fit")
        .lines()
        .map(|l| format!("/* {} */\n", l.trim_start_matches("// ")))
        .collect::<String>();
    let mut s = banner;
    s += &format!("#ifndef {guard}\n#define {guard}\n\n#include <math.h>\n\n");
    s += &src.tables(true);
    s += &src.helpers();
    s += &src.lookups();
    s += &src.fill(
        "/* f(wo, wi) per channel (1/sr); zero when either direction is at or below the horizon. */
INLINE void @eval(const REAL wo[3], const REAL wi[3], REAL f[3]) {
    REAL wox = wo[0]; REAL woy = wo[1]; REAL woz = wo[2];
    REAL wix = wi[0]; REAL wiy = wi[1]; REAL wiz = wi[2];
",
    );
    s += &src.eval_body(None, None);
    s += "    f[0] = r0; f[1] = r1; f[2] = r2;\n}\n";
    s += &src.sampler();
    s += &src.fill(
        "/* Density per solid angle of wi with which @sample draws wi for wo. */
INLINE REAL @pdf(const REAL wo[3], const REAL wi[3]) {
    return @pdf_s(wo[0], wo[1], wo[2], wi[0], wi[1], wi[2]);
}
/* Draws wi for wo: uc picks the component, u the direction (numbers outside
   [0, 1] are clamped). Returns 0, with pdf and f zero, when the draw leaves
   the upper hemisphere (that mass is lost). */
INLINE int @sample(const REAL wo[3], REAL uc, const REAL u[2], REAL wi_out[3], REAL f_out[3], REAL *pdf_out) {
    REAL wox = wo[0]; REAL woy = wo[1]; REAL woz = wo[2];
    REAL u0 = u[0]; REAL u1 = u[1];
",
    );
    s += &src.sample_body();
    s += &src.fill(
        "    wi_out[0] = wix; wi_out[1] = wiy; wi_out[2] = wiz;
    *pdf_out = pdf;
    if (ok == 1) @eval(wo, wi_out, f_out); else { f_out[0] = 0.0; f_out[1] = 0.0; f_out[2] = 0.0; }
    return ok;
}
",
    );
    s += &format!("\n#endif /* {guard} */\n");
    Ok(s)
}
