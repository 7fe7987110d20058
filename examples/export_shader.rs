//! Writes a model (`.json` / `.npfb`) as a shader or C export, the format
//! chosen by the output's extension: `.brdf` (BRDF Explorer), `.glsl`,
//! `.h`. Until `npf export` takes these formats:
//!
//!     cargo run --release --example export_shader -- MODEL OUT [--force]
//!
//! `MODEL` may also be `known` (a synthetic two-lobe model).

use npf::export::shader;
use std::path::Path;
use std::process::ExitCode;

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let force = args.iter().any(|a| a == "--force");
    let paths: Vec<&String> = args.iter().filter(|a| *a != "--force").collect();
    let [model_path, out] = paths[..] else {
        return Err("usage: export_shader MODEL OUT [--force]".into());
    };
    let model = if model_path == "known" {
        npf::synth::known_factor_model(npf::model::Layout::default(), &[0.1, 0.35])
    } else {
        npf::modelfile::read(Path::new(model_path))
            .map_err(|e| e.to_string())?
            .model
    };
    let out = Path::new(out);
    let ext = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    let t = std::time::Instant::now();
    let text = match ext.to_ascii_lowercase().as_str() {
        "brdf" => shader::brdf_explorer(&model),
        "glsl" => shader::glsl(&model),
        "h" => shader::c_header(&model),
        _ => {
            return Err(format!(
                "{}: unknown extension (use .brdf, .glsl or .h)",
                out.display()
            ))
        }
    }
    .map_err(|e| format!("{model_path}: {e}"))?;
    let secs = t.elapsed().as_secs_f64();
    npf::loaders::atomic::write_bytes_atomic(out, force, text.as_bytes())
        .map_err(|e| e.to_string())?;
    println!(
        "{}: {} bytes in {:.1} ms",
        out.display(),
        text.len(),
        secs * 1e3
    );
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("export_shader: {e}");
            ExitCode::FAILURE
        }
    }
}
