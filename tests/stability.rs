//! The stability suite in reduced form (1/40 of each table, 20 sweeps): on
//! every hard case the cubic-root method never raises the objective, never
//! produces NaN/inf or negative factors, and terminates. The other methods
//! run too and their outcomes are printed (`--nocapture`), not asserted;
//! `examples/stability_report.rs` runs the full grid.

use npf::samples::Weighting;
use npf::solver::GMethod;
use npf::stability::{cases, run, Config};

#[test]
fn cubic_root_fits_stay_monotone_finite_and_non_negative_on_every_hard_case() {
    for case in cases() {
        let clean = case.clean();
        let data = case.data(&clean, 40, 7);
        for (lobes, weighting, g_method) in [
            (3, Weighting::Compressive, GMethod::Cubic),
            (1, Weighting::CosineL2, GMethod::Cubic),
            (2, Weighting::Uniform, GMethod::Cubic),
            (3, Weighting::Compressive, GMethod::Golden),
            (3, Weighting::Compressive, GMethod::Fixed),
        ] {
            let config = Config {
                g_method,
                lobes,
                weighting,
            };
            let o = run(&case, &clean, &data, config, 20);
            eprintln!(
                "{:32} {:?}/{}/{:?}: sweeps {} rise {:.1e} finite {} non-neg {} degenerate {:?} rel {:.3e} log {:.3e} ({:.2} s)",
                o.case, g_method, lobes, weighting, o.sweeps, o.max_rise, o.finite, o.non_negative,
                o.degenerate, o.rel_cos_rmse, o.log_rmse, o.seconds
            );
            assert!(o.error.is_none(), "{}: {:?}", case.name, o.error);
            assert!(o.sweeps >= 1 && o.sweeps <= 20);
            if g_method == GMethod::Cubic {
                assert!(o.monotone(), "{}: {o:?}", case.name);
                assert!(o.finite, "{}: {o:?}", case.name);
                assert!(o.non_negative, "{}: {o:?}", case.name);
                assert!(
                    o.rel_cos_rmse.is_finite() && o.log_rmse.is_finite(),
                    "{o:?}"
                );
            }
        }
    }
}
