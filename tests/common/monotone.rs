//! The monotone-objective check shared by the fitting tests (included by
//! path, so tests that do not run the program need not build `common`).

use npf::solver::FitResult;

/// Every traced stage of `res` keeps the objective at or below the one
/// before it (gauge changes and cache rescaling are exact up to rounding).
pub fn assert_stages_monotone(res: &FitResult, label: &str) {
    let mut prev = res.initial_objective;
    for r in &res.history {
        for s in &r.stages {
            let e = s.objective.expect("traced");
            assert!(
                e <= prev * (1.0 + 1e-12),
                "{label} sweep {} {:?}: {prev} -> {e}",
                r.sweep,
                s.stage
            );
            prev = e;
        }
    }
}
