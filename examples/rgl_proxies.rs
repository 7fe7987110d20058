//! The proxy NDFs `npf export` chooses among for a `.bsdf` (issue 45):
//! each candidate's file read back and rendered by the render judge
//! against the model, and the time the choice took.
//!
//!     cargo run --release --example rgl_proxies -- MODEL.json [MODEL.json ...]
use npf::export::rgl::choose_proxy;
use npf::export::RglOptions;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        return Err("usage: rgl_proxies MODEL.json [MODEL.json ...]".into());
    }
    println!("model\tspread\tbroad\tlinear_db\tdisplay_db\tseconds");
    for path in &paths {
        let model = npf::modelfile::read(path.as_ref())?.model;
        let t = std::time::Instant::now();
        let (_, scores) = choose_proxy(&model, &RglOptions::default())?;
        let secs = t.elapsed().as_secs_f64();
        for s in &scores {
            println!(
                "{path}\t{}\t{:.3}\t{:.2}\t{:.2}\t{secs:.2}",
                s.proxy.spread.len(),
                s.proxy.broad,
                s.linear_db,
                s.display_db
            );
        }
    }
    Ok(())
}
