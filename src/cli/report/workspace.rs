//! What the report's jobs share: the materials, loaded once on first use,
//! and the file writes and one-thread pools every job uses.

use crate::cli::png::encode_png;
use crate::cli::{CliError, CliResult};
use crate::evaluation::Reference;
use crate::render::{Image, RenderOptions};
use npf_data_loaders::atomic::write_bytes_atomic;
use npf_data_loaders::{MeasuredSamples, MerlTable};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A material's table, its samples and its reference rendering.
pub struct MaterialData {
    /// The measured table.
    pub table: MerlTable,
    /// Its valid samples.
    pub samples: MeasuredSamples,
    /// Its rendering (the reference of every fit's PSNR).
    pub image: Image,
}

/// The materials of a report run, each loaded (and its reference image
/// written) on first use by whichever job needs it first.
pub struct Workspace<'a> {
    /// (name, path) of every material, sorted.
    pub materials: &'a [(String, PathBuf)],
    /// The report folder.
    pub out: &'a Path,
    /// Render settings of every image.
    pub render: RenderOptions,
    data: Vec<OnceLock<Result<MaterialData, String>>>,
}

impl<'a> Workspace<'a> {
    /// A workspace with nothing loaded yet.
    pub fn new(materials: &'a [(String, PathBuf)], out: &'a Path, render: RenderOptions) -> Self {
        Workspace {
            materials,
            out,
            render,
            data: materials.iter().map(|_| OnceLock::new()).collect(),
        }
    }

    /// Material `m`, loaded once.
    pub fn load(&self, m: usize) -> &Result<MaterialData, String> {
        self.data[m].get_or_init(|| {
            let (name, path) = &self.materials[m];
            let table = MerlTable::read(path).map_err(|e| e.to_string())?;
            let samples = table.samples(&path.display().to_string());
            if samples.samples.is_empty() {
                return Err(format!("{}: no valid samples", path.display()));
            }
            let image = Reference::new(&table, &samples, self.render).image;
            write_png(
                &self.out.join(name).join("reference.png"),
                image.res,
                &image.to_rgb8(),
            )
            .map_err(|e| e.to_string())?;
            Ok(MaterialData {
                table,
                samples,
                image,
            })
        })
    }
}

/// An I/O error naming its path.
pub fn io_err(path: &Path, e: std::io::Error) -> CliError {
    CliError::Message(format!("{}: {e}", path.display()))
}

/// Write (replacing) a report file atomically.
pub fn write_file(path: &Path, bytes: &[u8]) -> CliResult {
    write_bytes_atomic(path, true, bytes)?;
    Ok(())
}

/// Write a square 8-bit RGB image as PNG.
pub fn write_png(path: &Path, image_res: usize, rgb: &[u8]) -> CliResult {
    let png = encode_png(image_res as u32, image_res as u32, rgb)
        .map_err(|e| CliError::Message(format!("{}: {e}", path.display())))?;
    write_file(path, &png)
}

/// Run `f` in a fresh one-thread rayon pool.
pub fn one_thread<T: Send>(f: impl FnOnce() -> T + Send) -> Result<T, CliError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| CliError::Message(format!("cannot start a worker thread: {e}")))?;
    Ok(pool.install(f))
}
