//! The one small non-negative least-squares solver: exact, by trying every
//! support set. Used where the unknowns are few (the solver's diffuse and
//! scale update, at most 4 per channel; the GGX baseline's 3 linear
//! parameters), so 2^k Cholesky solves cost nothing and, unlike clamping an
//! unconstrained solution, the optimum is exact.

use nalgebra::{DMatrix, DVector};

/// argmin over x >= 0 of x'Gx - 2 r'x, by trying every support set. The
/// `current` point is a candidate too, so the result is never worse than it
/// (pass zeros when there is none).
pub fn nnls_enumerate(gram: &DMatrix<f64>, rhs: &DVector<f64>, current: &[f64]) -> Vec<f64> {
    let k = rhs.len();
    let mut best = current.to_vec();
    let mut best_val = quadratic(gram, rhs, &best);
    for mask in 1u32..(1 << k) {
        let idx: Vec<usize> = (0..k).filter(|&i| mask & (1 << i) != 0).collect();
        let sub = DMatrix::from_fn(idx.len(), idx.len(), |a, b| gram[(idx[a], idx[b])]);
        let subr = DVector::from_fn(idx.len(), |a, _| rhs[idx[a]]);
        let Some(chol) = sub.cholesky() else { continue };
        let sol = chol.solve(&subr);
        if sol.iter().any(|v| !(*v >= 0.0) || !v.is_finite()) {
            continue;
        }
        let mut x = vec![0.0; k];
        for (a, &i) in idx.iter().enumerate() {
            x[i] = sol[a];
        }
        let v = quadratic(gram, rhs, &x);
        if v < best_val {
            best_val = v;
            best = x;
        }
    }
    best
}

/// x'Gx - 2 r'x (the objective [`nnls_enumerate`] minimises, without the
/// constant y'Wy).
pub fn quadratic(gram: &DMatrix<f64>, rhs: &DVector<f64>, x: &[f64]) -> f64 {
    let xv = DVector::from_column_slice(x);
    (xv.transpose() * gram * &xv)[(0, 0)] - 2.0 * rhs.dot(&xv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nnls_matches_brute_force() {
        // G = B'B for a random-ish B; compare with a fine grid search in 2-D.
        let b = DMatrix::from_row_slice(3, 2, &[1.0, 0.5, 0.2, 1.0, 0.7, 0.3]);
        let y = DVector::from_column_slice(&[-1.0, 2.0, 0.5]);
        let gram = b.transpose() * &b;
        let rhs = b.transpose() * &y;
        let x = nnls_enumerate(&gram, &rhs, &[0.0, 0.0]);
        let f = |x0: f64, x1: f64| (&b * DVector::from_column_slice(&[x0, x1]) - &y).norm_squared();
        let mut best = f64::INFINITY;
        for i in 0..=400 {
            for j in 0..=400 {
                best = best.min(f(i as f64 * 0.01, j as f64 * 0.01));
            }
        }
        assert!(f(x[0], x[1]) <= best + 1e-12);
        assert!(x.iter().all(|&v| v >= 0.0));
    }
}
