//! The convergence experiment: how objective and rendering PSNR evolve with
//! sweeps and seconds for a few configurations on one material.

use super::configs::Configuration;
use super::workspace::{one_thread, Workspace};
use crate::evaluation::Reference;
use crate::fit::fit_model;
use serde::{Deserialize, Serialize};

/// One checkpoint of a convergence run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint {
    /// Sweeps the refit ran.
    pub sweeps: usize,
    /// Its fit seconds.
    pub seconds: f64,
    /// Its objective.
    pub objective: f64,
    /// Its rendering PSNR (dB) against the measured table.
    pub render_psnr_db: f64,
}

/// A convergence run: the full history of objectives, and the rendering
/// PSNR at sweep 1, 2, 4, 8, ... (refits stopped after k sweeps; the solver
/// is deterministic, so they are the full fit's first k sweeps).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Convergence {
    /// (sweep, objective, seconds) of every sweep of the full fit.
    pub history: Vec<(usize, f64, f64)>,
    /// The objective before the first sweep.
    pub initial_objective: f64,
    /// The refits' checkpoints, then the full fit's.
    pub checkpoints: Vec<Checkpoint>,
    /// Why the run failed, if it did.
    pub error: Option<String>,
}

/// The configurations the convergence chart compares.
pub const CONFIGS: [&str; 3] = ["sf-3", "sf-3-golden", "sf-3-fixed-g"];

/// Fit configuration `c` on material `m` fully, then refit it stopped after
/// 1, 2, 4, ... sweeps, recording objective and rendering PSNR; in one thread.
pub fn run(ws: &Workspace, m: usize, c: &Configuration, max_sweeps: Option<usize>) -> Convergence {
    let render_opts = ws.render;
    let r = one_thread(|| -> Result<Convergence, String> {
        let md = ws.load(m).as_ref().map_err(|e| e.clone())?;
        let config = c.fit_config(max_sweeps);
        let (full, _) =
            fit_model(&md.samples, &config, &mut |_, _| {}).map_err(|e| e.to_string())?;
        let reference = Reference {
            table: &md.table,
            samples: &md.samples,
            image: md.image.clone(),
            render: render_opts,
        };
        let mut conv = Convergence {
            history: full
                .history
                .iter()
                .map(|h| (h.sweep, h.objective, h.elapsed))
                .collect(),
            initial_objective: full.initial_objective,
            ..Default::default()
        };
        let n = full.history.len();
        let mut k = 1;
        while k < n {
            let mut cfg = config.clone();
            cfg.max_sweeps = k;
            let (part, _) =
                fit_model(&md.samples, &cfg, &mut |_, _| {}).map_err(|e| e.to_string())?;
            let bsdf = crate::bsdf::NpfBxdf::new(part.model.clone()).map_err(|e| e.to_string())?;
            let img = crate::render::render(render_opts, &bsdf);
            conv.checkpoints.push(Checkpoint {
                sweeps: part.history.len(),
                seconds: part.seconds,
                objective: part.objective,
                render_psnr_db: crate::render::psnr(&reference.image, &img)
                    .map_err(|e| e.to_string())?,
            });
            k *= 2;
        }
        let bsdf = crate::bsdf::NpfBxdf::new(full.model.clone()).map_err(|e| e.to_string())?;
        let img = crate::render::render(render_opts, &bsdf);
        conv.checkpoints.push(Checkpoint {
            sweeps: n,
            seconds: full.seconds,
            objective: full.objective,
            render_psnr_db: crate::render::psnr(&reference.image, &img)
                .map_err(|e| e.to_string())?,
        });
        Ok(conv)
    });
    match r {
        Ok(Ok(c)) => c,
        Ok(Err(e)) => Convergence {
            error: Some(e),
            ..Default::default()
        },
        Err(e) => Convergence {
            error: Some(e.to_string()),
            ..Default::default()
        },
    }
}
