//! The one generator of the exported source: the model's tables and the
//! functions that read them, written once in the common subset of GLSL
//! and C. A template names the prefix `@`, the real type `REAL` and the
//! function qualifier `INLINE `; the few spellings that differ (casts,
//! atan2, fmod) are small per-dialect helpers, so every formula below is
//! shared text.

use super::sampler::{separable_p, SamplerTables, VIEWS, VIEW_MAX_DEG};
use crate::grid::{Axis, Grid};
use crate::model::Model;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt::Write;

/// Node snap of the linear axes (`grid::axis`): a coordinate within this
/// of a node reads that node alone.
const SNAP: f64 = 1e-7;

/// The target language.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Dialect {
    /// GLSL 1.30 or later (BRDF Explorer uses 4.10): float arithmetic.
    Glsl,
    /// C99: double arithmetic on the f32 tables.
    C,
}

/// A real literal both languages read (Rust's shortest round-trip form).
fn lit(x: f64) -> String {
    let s = format!("{x:?}");
    if s.contains(['.', 'e', 'E']) {
        s
    } else {
        format!("{s}.0")
    }
}

/// The source of one model for one dialect.
pub(super) struct Source<'a> {
    model: &'a Model,
    tables: &'a SamplerTables,
    dialect: Dialect,
    prefix: &'a str,
}

impl<'a> Source<'a> {
    pub(super) fn new(
        model: &'a Model,
        tables: &'a SamplerTables,
        dialect: Dialect,
        prefix: &'a str,
    ) -> Self {
        Source {
            model,
            tables,
            dialect,
            prefix,
        }
    }

    /// Template expansion: `@` the prefix, `REAL` the real type, `INLINE `
    /// the function qualifier.
    pub(super) fn fill(&self, template: &str) -> String {
        let (real, inline) = match self.dialect {
            Dialect::Glsl => ("float", ""),
            Dialect::C => ("double", "static inline "),
        };
        template
            .replace('@', &format!("{}_", self.prefix))
            .replace("REAL", real)
            .replace("INLINE ", inline)
    }

    /// A `const float` table, eight values a line.
    fn array(&self, name: &str, values: &[f32]) -> String {
        let n = values.len();
        let items: Vec<String> = values
            .iter()
            .map(|v| match self.dialect {
                Dialect::Glsl => lit(*v as f64),
                Dialect::C => format!("{v:?}f"),
            })
            .collect();
        let body = items
            .chunks(8)
            .map(|c| format!("    {}", c.join(", ")))
            .collect::<Vec<_>>()
            .join(",\n");
        let name = self.fill(name);
        match self.dialect {
            Dialect::Glsl => format!("const float {name}[{n}] = float[{n}](\n{body}\n);\n"),
            Dialect::C => format!("static const float {name}[{n}] = {{\n{body}\n}};\n"),
        }
    }

    /// Every table: factors as the model stores them, then (when
    /// `with_sampler`) the sampler's.
    pub(super) fn tables(&self, with_sampler: bool) -> String {
        let m = self.model;
        let cat = |f: &dyn Fn(&crate::model::Lobe) -> &Vec<f32>| -> Vec<f32> {
            m.lobes.iter().flat_map(|l| f(l).iter().copied()).collect()
        };
        let fresnel: Vec<f32> = m.fresnel.iter().flatten().copied().collect();
        let mut s = String::new();
        s += "// Factor tables, exactly as the model stores them: D and G per lobe\n";
        s += "// (row-major theta x phi when 2-D), F per channel.\n";
        s += &self.array("@D", &cat(&|l| &l.d));
        s += &self.array("@G", &cat(&|l| &l.g));
        s += &self.array("@F", &fresnel);
        if let Some(p) = separable_p(m) {
            s += "// The separable diffuse factor's P (uniform theta nodes over [0, pi/2]).\n";
            s += &self.array("@P", p);
        }
        if with_sampler {
            s += "// Sampler: cell edges in t = sin^2 theta_h, each lobe's cdf at the\n";
            s += &format!(
                "// edges, component probabilities at {VIEWS} view angles (diffuse first).\n"
            );
            s += &self.array("@EDGES", &self.tables.edges);
            s += &self.array("@CDF", &self.tables.cdf);
            s += &self.array("@SEL", &self.tables.selection);
        }
        s
    }

    /// The small helpers whose spelling differs between the dialects.
    pub(super) fn helpers(&self) -> String {
        let tau = lit(TAU);
        let t = match self.dialect {
            Dialect::Glsl => format!(
                "REAL @clampr(REAL x, REAL a, REAL b) {{ return x < a ? a : (x > b ? b : x); }}
REAL @minr(REAL a, REAL b) {{ return min(a, b); }}
REAL @maxr(REAL a, REAL b) {{ return max(a, b); }}
int @floori(REAL x) {{ return int(floor(x)); }}
REAL @tor(int i) {{ return float(i); }}
REAL @atan2(REAL y, REAL x) {{ return (x == 0.0 && y == 0.0) ? 0.0 : atan(y, x); }}
REAL @wrap(REAL phi) {{ return mod(phi, {tau}); }}
"
            ),
            Dialect::C => format!(
                "INLINE REAL @clampr(REAL x, REAL a, REAL b) {{ return x < a ? a : (x > b ? b : x); }}
INLINE REAL @minr(REAL a, REAL b) {{ return fmin(a, b); }}
INLINE REAL @maxr(REAL a, REAL b) {{ return fmax(a, b); }}
INLINE int @floori(REAL x) {{ return (int)floor(x); }}
INLINE REAL @tor(int i) {{ return (REAL)i; }}
INLINE REAL @atan2(REAL y, REAL x) {{ return atan2(y, x); }}
INLINE REAL @wrap(REAL phi) {{ REAL r = fmod(phi, {tau}); return r < 0.0 ? r + {tau} : r; }}
"
            ),
        };
        // Random numbers: clamped into [0, 1], NaN to 0 (as npf's sampler).
        let unit = "INLINE REAL @unit(REAL x) { return x >= 0.0 ? (x <= 1.0 ? x : 1.0) : 0.0; }\n";
        self.fill(&(t + unit))
    }

    /// The interpolation of one factor table: `INLINE REAL @name(int base,
    /// REAL theta, REAL phi)` reads the table `@table` from entry `base`.
    pub(super) fn lookup(&self, name: &str, table: &str, grid: Grid) -> String {
        let mut s = format!("INLINE REAL @{name}(int base, REAL theta, REAL phi) {{\n");
        s += "    int ti[4]; REAL tw[4];\n";
        s += "    for (int k = 0; k < 4; k++) { ti[k] = 0; tw[k] = 0.0; }\n";
        s += &format!(
            "    REAL x = @clampr(theta / {}, 0.0, 1.0);\n",
            lit(FRAC_PI_2)
        );
        s += &theta_stencil(grid.theta);
        match grid.phi {
            None => {
                if self.dialect == Dialect::C {
                    s += "    (void)phi;\n";
                }
                s += "    REAL v = 0.0;\n";
                s += "    for (int k = 0; k < 4; k++) {\n";
                s += &format!("        if (tw[k] != 0.0) v += tw[k] * @{table}[base + ti[k]];\n");
                s += "    }\n";
            }
            Some(p) => {
                let n = p.n;
                s += "    int p0 = 0; int p1 = 0; REAL pw0 = 1.0; REAL pw1 = 0.0;\n";
                if n > 1 {
                    s += &format!(
                        "    REAL q = @clampr(@wrap(phi) / {} * {}, 0.0, {});\n",
                        lit(TAU),
                        lit(n as f64),
                        lit(n as f64)
                    );
                    s += &format!(
                        "    int j = @floori(q); if (j > {}) j = {};\n",
                        n - 1,
                        n - 1
                    );
                    s += "    REAL u = q - @tor(j);\n";
                    s += &format!(
                        "    if (u < {snap}) {{ p0 = j; }} else if (u > 1.0 - {snap}) {{ p0 = (j + 1) % {n}; }} else {{ p0 = j; p1 = (j + 1) % {n}; pw0 = 1.0 - u; pw1 = u; }}\n",
                        snap = lit(SNAP)
                    );
                }
                s += "    REAL v = 0.0;\n";
                s += "    for (int k = 0; k < 4; k++) {\n";
                // The pole row of a Catmull-Rom (G) axis is one direction
                // whatever phi: one value, the row's first (Grid::extend).
                if grid.theta.pole_tied() {
                    s += &format!(
                        "        if (ti[k] == 0) {{ if (tw[k] != 0.0) v += tw[k] * @{table}[base]; continue; }}\n"
                    );
                }
                s += "        REAL a = tw[k] * pw0; REAL b = tw[k] * pw1;\n";
                s +=
                    &format!("        if (a != 0.0) v += a * @{table}[base + ti[k] * {n} + p0];\n");
                s +=
                    &format!("        if (b != 0.0) v += b * @{table}[base + ti[k] * {n} + p1];\n");
                s += "    }\n";
            }
        }
        s += "    return v;\n}\n";
        self.fill(&s)
    }

    /// The three factor lookups, and P's for a separable diffuse form.
    pub(super) fn lookups(&self) -> String {
        let l = &self.model.layout;
        let p =
            separable_p(self.model).map(|p| ("p", "P", Grid::line(Axis::Closed { n: p.len() })));
        [("d", "D", l.d), ("f", "F", l.f), ("g", "G", l.g)]
            .into_iter()
            .chain(p)
            .map(|(n, t, g)| self.lookup(n, t, g))
            .collect()
    }

    /// The body of eval: reads `wox .. wiz`, declares and sets `r0, r1, r2`
    /// (exactly `Model::eval`). `diffuse_on` and `lobe_on(m)` are boolean
    /// expressions switching terms (BRDF Explorer's parameters), `None` for
    /// always on.
    pub(super) fn eval_body(
        &self,
        diffuse_on: Option<&str>,
        lobe_on: Option<&dyn Fn(usize) -> String>,
    ) -> String {
        let m = self.model;
        let l = &m.layout;
        let (nd, ng, nf) = (l.d.len(), l.g.len(), l.f.len());
        let mut s = String::from(
            "    REAL r0 = 0.0; REAL r1 = 0.0; REAL r2 = 0.0;
    if (wiz > 0.0 && woz > 0.0) {
        // Rusinkiewicz angles, as npf_data_loaders::geometry computes them.
        REAL hx = wix + wox; REAL hy = wiy + woy; REAL hz = wiz + woz;
        REAL hn = sqrt(hx * hx + hy * hy + hz * hz);
        hx = hx / hn; hy = hy / hn; hz = hz / hn;
        REAL theta_h = acos(@clampr(hz, -1.0, 1.0));
",
        );
        // Azimuths only where a 2-D table reads them: the 1-D layouts skip
        // the trigonometry (theta_d from wi.h, the same angle to rounding).
        if l.f.is_1d() && l.d.is_1d() {
            s += "        REAL phi_h = 0.0; REAL phi_d = 0.0;
        REAL theta_d = acos(@clampr(wix * hx + wiy * hy + wiz * hz, -1.0, 1.0));
";
        } else {
            s += "        REAL phi_h = @atan2(hy, hx);
        REAL sz = sin(-phi_h); REAL cz = cos(-phi_h);
        REAL vx = cz * wix - sz * wiy; REAL vy = sz * wix + cz * wiy; REAL vz = wiz;
        REAL sy = sin(-theta_h); REAL cy = cos(-theta_h);
        REAL dx = cy * vx + sy * vz; REAL dy = vy; REAL dz = -sy * vx + cy * vz;
        REAL theta_d = acos(@clampr(dz, -1.0, 1.0)); REAL phi_d = @atan2(dy, dx);
";
        }
        s += "        REAL theta_i = acos(@clampr(wiz, -1.0, 1.0));
        REAL theta_o = acos(@clampr(woz, -1.0, 1.0));
";
        s += if l.g.is_1d() {
            "        REAL phi_i = 0.0; REAL phi_o = 0.0;\n"
        } else {
            "        REAL phi_i = @atan2(wiy, wix); REAL phi_o = @atan2(woy, wox);\n"
        };
        s += "        REAL ci = cos(theta_i); REAL co = cos(theta_o);
        if (ci > 0.0 && co > 0.0) {
";
        for c in 0..3 {
            let _ = writeln!(s, "            REAL f{c} = @f({}, theta_d, phi_d);", c * nf);
        }
        // The separable form's factor P(theta_i) P(theta_o), shared by the channels.
        let mut form = "";
        if separable_p(m).is_some() {
            s += "            REAL pp = @p(0, theta_i, 0.0) * @p(0, theta_o, 0.0);\n";
            form = " * pp";
        }
        for c in 0..3 {
            let d = lit(m.diffuse[c] as f64) + form;
            match diffuse_on {
                Some(on) => {
                    let _ = writeln!(s, "            r{c} = {on} ? {d} : 0.0;");
                }
                None => {
                    let _ = writeln!(s, "            r{c} = {d};");
                }
            }
        }
        for (k, lobe) in m.lobes.iter().enumerate() {
            let guard = lobe_on.map_or_else(|| "true".to_string(), |f| f(k));
            let open = if guard == "true" {
                "            {".to_string()
            } else {
                format!("            if ({guard}) {{")
            };
            let _ = writeln!(s, "{open}");
            let _ = writeln!(
                s,
                "                REAL spec = @d({}, theta_h, phi_h) * @g({g}, theta_i, phi_i) * @g({g}, theta_o, phi_o) / (ci * co);",
                k * nd,
                g = k * ng
            );
            for c in 0..3 {
                let _ = writeln!(
                    s,
                    "                r{c} += ({} * f{c}) * spec;",
                    lit(lobe.s[c] as f64)
                );
            }
            s += "            }\n";
        }
        s += "            // Catmull-Rom G can undershoot: a BRDF is never negative.
            r0 = @maxr(r0, 0.0); r1 = @maxr(r1, 0.0); r2 = @maxr(r2, 0.0);
        }
    }
";
        self.fill(&s)
    }

    /// The sampler's functions: `@selection`, `@density`, `@sample_t` and
    /// the scalar mixture pdf `@pdf_s(wo, wi)`.
    pub(super) fn sampler(&self) -> String {
        let lobes = self.model.lobes.len();
        let nc = 1 + lobes;
        let ne = self.tables.edges.len();
        let views = VIEWS;
        let s = format!(
            "// Probability of component c (0 diffuse, 1 + m lobe m) at a view,
// linear in theta_o between the table's view angles.
INLINE REAL @selection(REAL cos_o, int c) {{
    REAL x = acos(@clampr(cos_o, -1.0, 1.0)) * {deg};
    x = @clampr(x, 0.0, {vlast});
    int k = @floori(x); if (k > {vk}) k = {vk};
    REAL w = x - @tor(k);
    return (1.0 - w) * @SEL[k * {nc} + c] + w * @SEL[(k + 1) * {nc} + c];
}}
// Density in t = sin^2 theta_h of lobe m's half-vector table.
INLINE REAL @density(int m, REAL t) {{
    if (!(t >= 0.0 && t < 1.0)) return 0.0;
    int lo = 0; int hi = {ne1};
    while (hi - lo > 1) {{ int mid = (lo + hi) / 2; if (@EDGES[mid] <= t) lo = mid; else hi = mid; }}
    int b = m * {ne} + lo;
    return (@CDF[b + 1] - @CDF[b]) / (@EDGES[lo + 1] - @EDGES[lo]);
}}
// t = sin^2 theta_h drawn from lobe m's table (cells of zero probability never).
INLINE REAL @sample_t(int m, REAL u) {{
    int b = m * {ne};
    int lo = 0; int hi = {ne1};
    while (hi - lo > 1) {{ int mid = (lo + hi) / 2; if (@CDF[b + mid] <= u) lo = mid; else hi = mid; }}
    while (lo > 0 && @CDF[b + lo + 1] <= @CDF[b + lo]) lo -= 1;
    REAL p = @CDF[b + lo + 1] - @CDF[b + lo];
    REAL du = p > 0.0 ? @clampr((u - @CDF[b + lo]) / p, 0.0, 1.0) : 0.5;
    REAL a = @EDGES[lo]; REAL e = @EDGES[lo + 1];
    REAL x = a + du * (e - a);
    return x < e ? x : a;
}}
// The mixture density per solid angle of wi: what sample draws wi with.
INLINE REAL @pdf_s(REAL wox, REAL woy, REAL woz, REAL wix, REAL wiy, REAL wiz) {{
    if (!(woz > 0.0 && wiz > 0.0)) return 0.0;
    REAL pdf = 0.0;
    REAL pd = @selection(woz, 0);
    if (pd > 0.0) pdf += pd * wiz / {pi};
    REAL sx = wix + wox; REAL sy = wiy + woy; REAL sz = wiz + woz;
    REAL n2 = sx * sx + sy * sy + sz * sz;
    if (!(n2 > 0.0)) return pdf;
    REAL inv = 1.0 / sqrt(n2);
    REAL hz = sz * inv;
    REAL woh = (wox * sx + woy * sy + woz * sz) * inv;
    REAL t = @minr((sx * sx + sy * sy) / n2, 1.0);
    if (hz > 0.0 && woh > 0.0) {{
        for (int m = 0; m < {lobes}; m++) {{
            REAL p = @selection(woz, m + 1);
            // Half-vector density p_t cos theta_h / pi, times 1 / (4 wo.h).
            if (p > 0.0) pdf += p * @density(m, t) * hz / {pi} / (4.0 * woh);
        }}
    }}
    return pdf;
}}
",
            deg = lit(180.0 / PI / VIEW_MAX_DEG * (views - 1) as f64),
            vlast = lit((views - 1) as f64),
            vk = views - 2,
            ne1 = ne - 1,
            pi = lit(PI),
        );
        self.fill(&s)
    }

    /// The body of sample: reads `wox .. woz`, `uc`, `u0`, `u1`; declares
    /// and sets `wix, wiy, wiz`, `pdf` and `ok` (1 when the draw carries
    /// light, 0 when it left the hemisphere: then pdf is 0).
    pub(super) fn sample_body(&self) -> String {
        let nc = 1 + self.model.lobes.len();
        let s = format!(
            "    REAL wix = 0.0; REAL wiy = 0.0; REAL wiz = 1.0; REAL pdf = 0.0; int ok = 0;
    if (woz > 0.0) {{
        int comp = -1; int last = -1; REAL acc = 0.0;
        for (int c = 0; c < {nc}; c++) {{
            REAL p = @selection(woz, c);
            if (p > 0.0) {{ last = c; acc += p; if (comp < 0 && uc < acc) comp = c; }}
        }}
        if (comp < 0) comp = last;
        REAL v0 = @unit(u0); REAL v1 = @unit(u1);
        int drawn = 0;
        if (comp == 0) {{
            // Cosine-weighted hemisphere.
            REAL r = sqrt(v0); REAL a = {tau} * v1;
            wix = r * cos(a); wiy = r * sin(a); wiz = sqrt(@maxr(1.0 - v0, 0.0));
            drawn = 1;
        }} else if (comp > 0) {{
            // Half vector from the lobe's table, reflected about wo.
            REAL t = @sample_t(comp - 1, v0);
            REAL sh = sqrt(t); REAL ch = sqrt(@maxr(1.0 - t, 0.0)); REAL a = {tau} * v1;
            REAL hx = sh * cos(a); REAL hy = sh * sin(a); REAL hz = ch;
            REAL woh = wox * hx + woy * hy + woz * hz;
            if (woh > 0.0) {{
                wix = 2.0 * woh * hx - wox; wiy = 2.0 * woh * hy - woy; wiz = 2.0 * woh * hz - woz;
                drawn = 1;
            }}
        }}
        if (drawn == 1 && wiz > 0.0) {{
            pdf = @pdf_s(wox, woy, woz, wix, wiy, wiz);
            if (pdf > 0.0) ok = 1; else pdf = 0.0;
        }}
    }}
",
            tau = lit(TAU)
        );
        self.fill(&s)
    }
}

/// The theta part of a lookup: sets the slots `ti`, `tw` from `x` (the
/// angle over pi/2, clamped), as `grid::axis` builds its stencils.
fn theta_stencil(axis: Axis) -> String {
    let snap = lit(SNAP);
    match axis {
        Axis::SqrtAngle { n } | Axis::Uniform { n } | Axis::Squared { n } | Axis::Closed { n } => {
            if n == 1 {
                return "    ti[0] = 0; tw[0] = 1.0;\n".into();
            }
            let p = match axis {
                Axis::SqrtAngle { .. } => format!("sqrt(x) * {}", lit(n as f64)),
                // Squared: sqrt(x / span) * (n - 1), span = (n - 1) / n.
                Axis::Squared { .. } => format!(
                    "sqrt(x * {}) * {}",
                    lit(n as f64 / (n - 1) as f64),
                    lit((n - 1) as f64)
                ),
                Axis::Closed { .. } => format!("x * {}", lit((n - 1) as f64)),
                _ => format!("x * {}", lit(n as f64)),
            };
            format!(
                "    REAL p = {p};
    if (p >= {last} - {snap}) {{ ti[0] = {lastn}; tw[0] = 1.0; }}
    else {{
        int i = @floori(p); REAL t = p - @tor(i);
        if (t < {snap}) {{ ti[0] = i; tw[0] = 1.0; }}
        else if (t > 1.0 - {snap}) {{ ti[0] = i + 1; tw[0] = 1.0; }}
        else {{ ti[0] = i; tw[0] = 1.0 - t; ti[1] = i + 1; tw[1] = t; }}
    }}
",
                last = lit((n - 1) as f64),
                lastn = n - 1
            )
        }
        Axis::CatmullRom { n } => format!(
            "    // pbrt's Catmull-Rom weights: centred tangents inside, chords at the ends.
    REAL p = x * {span};
    int i = @floori(p); if (i > {im}) i = {im};
    REAL t = @clampr(p - @tor(i), 0.0, 1.0);
    REAL t2 = t * t; REAL t3 = t * t * t;
    REAL w0 = 0.0; REAL w1 = 2.0 * t3 - 3.0 * t2 + 1.0; REAL w2 = -2.0 * t3 + 3.0 * t2; REAL w3 = 0.0;
    REAL h10 = t3 - 2.0 * t2 + t; REAL h11 = t3 - t2;
    if (i > 0) {{ REAL a = 0.5 * h10; w0 = -a; w2 += a; }} else {{ w1 -= h10; w2 += h10; }}
    if (i + 2 < {n}) {{ REAL b = 0.5 * h11; w1 -= b; w3 = b; }} else {{ w1 -= h11; w2 += h11; }}
    if (i > 0) {{ ti[0] = i - 1; tw[0] = w0; }}
    ti[1] = i; tw[1] = w1; ti[2] = i + 1; tw[2] = w2;
    if (i + 2 < {n}) {{ ti[3] = i + 2; tw[3] = w3; }}
",
            span = lit((n - 1) as f64),
            im = n - 2
        ),
    }
}
