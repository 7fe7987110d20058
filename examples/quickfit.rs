//! Development check: fit a MERL file and print timing and errors.
use npf::{metrics, model::Layout, samples::*, solver::*};
fn main() {
    let path = std::env::args().nth(1).expect("path");
    let lobes: usize = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(3);
    let t = std::time::Instant::now();
    let table = match path.as_str() {
        "known" => npf::reconstruct::to_merl(&npf::synth::known_factor_model(
            Layout::default(),
            &[0.05, 0.2, 0.5],
        )),
        p if p.starts_with("case:") => {
            let case = npf::stability::cases()
                .into_iter()
                .find(|c| c.name.contains(&p[5..]))
                .expect("case");
            npf::loaders::MerlTable::from_fn(|th, td, pd| {
                (case.truth)(&npf::loaders::geometry::Angles::from_half_diff(
                    th, 0.0, td, pd,
                ))
            })
        }
        _ => npf::loaders::MerlTable::read(path.as_ref()).unwrap(),
    };
    let samples = table.samples(&path);
    let t_load = t.elapsed().as_secs_f64();
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
    let mut so = SampleOptions::default();
    if let Some(v) = env("THH") {
        so.max_theta_h_deg = v;
    }
    if std::env::var("L2").is_ok() {
        so.weighting = Weighting::CosineL2;
    }
    if let Some(v) = env("TH") {
        so.max_theta_deg = v;
    }
    let n = env("N").map_or(90, |v| v as usize);
    let set = FitSet::build(&samples, Layout::isotropic(n), so).unwrap();
    println!(
        "load {t_load:.2}s build {:.2}s stats {:?} ~{} MB",
        t.elapsed().as_secs_f64() - t_load,
        set.stats,
        set.heap_bytes() >> 20
    );
    let mut obs = |r: &SweepReport| {
        if r.sweep <= 3 || r.sweep % 10 == 0 {
            println!(
                "sweep {:3} E {:.6e} rel {:.2e} t {:.2}s x {} g {:?}",
                r.sweep,
                r.objective,
                r.rel_decrease,
                r.elapsed,
                r.extrapolated,
                r.g_passes
                    .iter()
                    .map(|g| (g.accepted, g.rejected))
                    .collect::<Vec<_>>()
            );
            println!(
                "   {}",
                r.stages
                    .iter()
                    .map(|s| format!("{:?}:{:.0}ms", s.stage, s.seconds * 1e3))
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
    };
    let accelerate = std::env::var("NOACC").is_err();
    let mut opts = FitOptions {
        lobes,
        accelerate,
        ..Default::default()
    };
    if let Some(v) = env("MAXS") {
        opts.max_sweeps = v as usize;
    }
    if std::env::var("FREE").is_ok() {
        opts.d_monotone_from_deg = None;
    }
    if let Some(v) = env("TOL") {
        opts.tol = v;
    }
    let res = Executor::new(&set, opts).observe(&mut obs).run().unwrap();
    println!(
        "fit {:.2}s sweeps {} converged {} E0 {:.4e} E {:.4e}",
        res.seconds,
        res.history.len(),
        res.converged,
        res.initial_objective,
        res.objective
    );
    let m = metrics::compare_model(&samples, 85.0, &res.model);
    println!("{m:?}");
    for cut in [30.0, 60.0, 80.0] {
        println!(
            "cut {cut}: {:?}",
            metrics::compare_model(&samples, cut, &res.model)
        );
    }
    for (i, l) in res.model.lobes.iter().enumerate() {
        println!(
            "lobe {i} s {:?} D[0..4] {:?} Dmax {:.3e} G[0,30,60,80,85] {:?}",
            l.s,
            &l.d[..4],
            l.d.iter().cloned().fold(0f32, f32::max),
            [l.g[0], l.g[30], l.g[60], l.g[80], l.g[85]]
        );
    }
    if std::env::var("DUMP").is_ok() {
        for l in &res.model.lobes {
            println!("D {:?}", l.d);
            println!("G {:?}", l.g);
        }
    }
    println!(
        "diffuse {:?} F0..: {:?}",
        res.model.diffuse,
        [
            res.model.fresnel[0][0],
            res.model.fresnel[0][45],
            res.model.fresnel[0][85]
        ]
    );
}
// (debug) dump
