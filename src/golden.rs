//! The one golden-section search (the GGX baseline's roughness, the
//! solver's golden G step): a unimodal function's minimum bracketed by
//! shrinking [a, b] by the golden ratio per evaluation.

/// Where a search stopped: the bracket [a, b] and its two interior points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bracket {
    /// Lower end.
    pub a: f64,
    /// Upper end.
    pub b: f64,
    /// Lower interior point.
    pub x1: f64,
    /// f(x1).
    pub f1: f64,
    /// Upper interior point.
    pub x2: f64,
    /// f(x2).
    pub f2: f64,
}

impl Bracket {
    /// The better interior point and its value (x1 on a tie).
    pub fn best(&self) -> (f64, f64) {
        if self.f1 <= self.f2 {
            (self.x1, self.f1)
        } else {
            (self.x2, self.f2)
        }
    }
}

/// Golden-section search of `f` over [a, b]: at most `iters` steps, none
/// once `|b - a| < tol` (0: always `iters`). On `f(x1) == f(x2)` the
/// bracket keeps its lower part when `ties_left`, its upper part otherwise.
/// f is evaluated at x1 first, then x2, then once per step.
pub fn golden_section(
    mut f: impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
    iters: usize,
    tol: f64,
    ties_left: bool,
) -> Bracket {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (a, b);
    let (mut x1, mut x2) = (b - r * (b - a), a + r * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..iters {
        if (b - a).abs() < tol {
            break;
        }
        if f1 < f2 || (ties_left && f1 == f2) {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - r * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + r * (b - a);
            f2 = f(x2);
        }
    }
    Bracket {
        a,
        b,
        x1,
        f1,
        x2,
        f2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_parabola_minimum() {
        let br = golden_section(|x| (x - 0.3).powi(2), -1.0, 2.0, 200, 1e-10, true);
        assert!((br.best().0 - 0.3).abs() < 1e-8);
        assert!(br.a <= 0.3 && 0.3 <= br.b);
    }
}
