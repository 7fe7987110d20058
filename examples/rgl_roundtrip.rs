//! Where a `.bsdf` export differs from the model it was written from
//! (issue 45's round trip): relative error of the file's value (read as
//! npf reads it) against the model's, binned by the conditioning angle
//! theta_i and by theta_h, over a (theta_h, theta_d, phi_d) grid; with a
//! third argument, also the file as npf's fit reads it (a MERL table).
//!
//!     cargo run --release --example rgl_roundtrip -- MODEL.json MODEL.bsdf [READ_BACK.binary]
use npf::loaders::geometry::directions_from_half_diff;
use npf::loaders::rgl_brdf::RglBrdf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (model, file, out) = match args.as_slice() {
        [m, f] => (m, f, None),
        [m, f, o] => (m, f, Some(o)),
        _ => return Err("usage: rgl_roundtrip MODEL.json MODEL.bsdf [READ_BACK.binary]".into()),
    };
    let model = npf::modelfile::read(model.as_ref())?.model;
    let rgl = RglBrdf::read(file.as_ref())?;
    if let Some(out) = out {
        rgl.to_merl()?.write(out.as_ref(), false)?;
    }
    // bins of theta_i (the file's conditioning direction = MERL's wo) and theta_h, 10 deg
    let mut by_ti = vec![(0.0f64, 0.0f64, 0usize); 10];
    let mut by_th = vec![(0.0f64, 0.0f64, 0usize); 10];
    let mut rel_all = Vec::new();
    let (nh, nd, np) = (90, 90, 180);
    for ih in 0..nh {
        let u = (ih as f64 + 0.5) / nh as f64;
        let th = u * u * std::f64::consts::FRAC_PI_2;
        for id in 0..nd {
            let td = (id as f64 + 0.5) / nd as f64 * std::f64::consts::FRAC_PI_2;
            for ip in 0..np {
                let pd = (ip as f64 + 0.5) / np as f64 * std::f64::consts::PI;
                let (wi, wo) = directions_from_half_diff(th, 0.0, td, pd);
                if wi[2] <= 0.0 || wo[2] <= 0.0 || wo[2] < rgl.max_theta_i().cos() {
                    continue;
                }
                let m = model.eval(wo, wi);
                let r = rgl.rgb(wo, wi);
                let ms: f64 = m.iter().sum();
                let rs: f64 = r.iter().sum();
                // cos-weighted absolute error, relative to the cos-weighted value
                let w = wi[2] * wo[2];
                let ti = wo[2].acos().to_degrees();
                for (bins, deg) in [(&mut by_ti, ti), (&mut by_th, th.to_degrees())] {
                    let b = &mut bins[((deg / 10.0) as usize).min(9)];
                    b.0 += ((rs - ms) * w).powi(2);
                    b.1 += (ms * w).powi(2);
                    b.2 += 1;
                }
                if ms > 0.0 {
                    rel_all.push((rs - ms).abs() / ms);
                }
            }
        }
    }
    rel_all.sort_by(f64::total_cmp);
    let q = |p: f64| rel_all[((rel_all.len() - 1) as f64 * p) as usize];
    println!(
        "relative error: median {:.4} p90 {:.4} p99 {:.4} max {:.3}",
        q(0.5),
        q(0.9),
        q(0.99),
        q(1.0)
    );
    for (name, bins) in [("theta_i", &by_ti), ("theta_h", &by_th)] {
        for (k, (e, v, n)) in bins.iter().enumerate() {
            if *n > 0 {
                println!(
                    "{name} {:2}-{:2}: cos-weighted relative RMS {:.4} ({n} pairs)",
                    k * 10,
                    k * 10 + 10,
                    (e / v).sqrt()
                );
            }
        }
    }
    Ok(())
}
