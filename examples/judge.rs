//! The render judge (`npf::judge`) on a measured table and fitted models:
//! each model's PSNR per scene and the mean, and the judge's time.
//!
//!     cargo run --release --example judge -- TABLE.binary MODEL.json [MODEL.json ...]
//!
//! NPF_JUDGE_READER=truncate and NPF_JUDGE_ENV=sphere change the reading
//! of the table and the environment quadrature (see the code).
use npf::bsdf::{EvaluatedModel, InterpolatedMerl};
use npf::judge::{judge_options, Judge};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (table, models) = args
        .split_first()
        .ok_or("usage: judge TABLE.binary MODEL.json [MODEL.json ...]")?;
    let table = npf::loaders::MerlTable::read(table.as_ref())?;
    let t = std::time::Instant::now();
    // NPF_JUDGE_READER=truncate reads the table by its own lookup (each
    // node held across its bin), NPF_JUDGE_ENV=sphere uses the sphere grid.
    let mut opts = judge_options();
    if std::env::var("NPF_JUDGE_ENV").as_deref() == Ok("sphere") {
        opts.env = npf::render::EnvQuadrature::Sphere;
    }
    let judge = if std::env::var("NPF_JUDGE_READER").as_deref() == Ok("truncate") {
        Judge::new(&table, opts)
    } else {
        Judge::new(&InterpolatedMerl(&table), opts)
    };
    println!("reference renders: {:.2} s", t.elapsed().as_secs_f64());
    println!(
        "model\t{}\tmean\tlinear: {}\tlinear mean\tseconds",
        judge.scene_names().join("\t"),
        judge.scene_names().join("\t")
    );
    for path in models {
        let t = std::time::Instant::now();
        // A .binary candidate (a fit reconstructed as a table) is read
        // as the reference is.
        let s = if path.ends_with(".binary") {
            let t = npf::loaders::MerlTable::read(path.as_ref())?;
            if std::env::var("NPF_JUDGE_READER").as_deref() == Ok("truncate") {
                judge.score(&t)
            } else {
                judge.score(&InterpolatedMerl(&t))
            }
        } else {
            judge.score(&EvaluatedModel::new(
                npf::modelfile::read(path.as_ref())?.model,
            )?)
        };
        let cells = |v: &[f64]| -> String {
            let c: Vec<String> = v.iter().map(|v| format!("{v:.3}")).collect();
            c.join("\t")
        };
        println!(
            "{path}\t{}\t{:.3}\t{}\t{:.3}\t{:.2}",
            cells(&s.psnr_db),
            s.mean_db,
            cells(&s.linear_psnr_db),
            s.linear_mean_db,
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
