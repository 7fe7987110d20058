//! Model selection: the smallest model that meets a target, or the best one
//! within a parameter budget.
//!
//! Candidates are the shared-factor model with 1 to 3 lobes and 30, 45 or
//! 90 values per factor table (same axes and interpolation, coarser
//! nodes), ordered by parameter count: from 156 (1 lobe, 30 values) to 822
//! (3 lobes, 90 values).

use crate::metrics::Metrics;
use crate::model::Layout;
use serde::{Deserialize, Serialize};

/// What a model must reach, on the error metrics of `npf fit` (over the
/// samples within the grazing cut-off) or on the rendering PSNR of
/// `npf compare` (docs/evaluation.md).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "metric", content = "value", rename_all = "kebab-case")]
pub enum Target {
    /// RMSE of log(1 + f cos theta_i) at most this.
    LogRmse(f64),
    /// Relative cosine-weighted RMSE at most this.
    RelRmse(f64),
    /// Rendering PSNR (dB, standard sphere and environment) at least this.
    Psnr(f64),
}

/// What a candidate fit scored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores {
    /// The candidate's error measures.
    pub metrics: Metrics,
    /// Present when the target needs it.
    pub render_psnr_db: Option<f64>,
}

impl From<Metrics> for Scores {
    fn from(metrics: Metrics) -> Self {
        Scores {
            metrics,
            render_psnr_db: None,
        }
    }
}

impl Target {
    /// The metric's value for a fit.
    pub fn value(&self, s: &Scores) -> f64 {
        match self {
            Target::LogRmse(_) => s.metrics.log_rmse,
            Target::RelRmse(_) => s.metrics.rel_cos_rmse,
            Target::Psnr(_) => s.render_psnr_db.unwrap_or(f64::NEG_INFINITY),
        }
    }

    /// Lower is better.
    fn badness(&self, value: f64) -> f64 {
        match self {
            Target::Psnr(_) => -value,
            _ => value,
        }
    }

    /// The value the metric must reach.
    pub fn threshold(&self) -> f64 {
        match *self {
            Target::LogRmse(t) | Target::RelRmse(t) | Target::Psnr(t) => t,
        }
    }

    /// Whether a fit's scores meet the target.
    pub fn met_by(&self, s: &Scores) -> bool {
        self.badness(self.value(s)) <= self.badness(self.threshold())
    }

    /// Whether scoring needs the rendering PSNR.
    pub fn needs_render(&self) -> bool {
        matches!(self, Target::Psnr(_))
    }

    /// The metric's name, for messages.
    pub fn name(&self) -> &'static str {
        match self {
            Target::LogRmse(_) => "log RMSE",
            Target::RelRmse(_) => "relative cosine-weighted RMSE",
            Target::Psnr(_) => "rendering PSNR (dB)",
        }
    }

    /// "<=" or ">=".
    pub fn relation(&self) -> &'static str {
        match self {
            Target::Psnr(_) => ">=",
            _ => "<=",
        }
    }
}

impl std::str::FromStr for Target {
    type Err = String;
    /// `log-rmse=0.01`, `rel-rmse=0.05` or `psnr=40`.
    fn from_str(s: &str) -> Result<Self, String> {
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| format!("target {s:?}: expected METRIC=VALUE, e.g. log-rmse=0.01"))?;
        let v: f64 = value
            .trim()
            .parse()
            .map_err(|_| format!("target {s:?}: {value:?} is not a number"))?;
        if !(v > 0.0 && v.is_finite()) {
            return Err(format!("target {s:?}: the value must be positive"));
        }
        match name.trim() {
            "log-rmse" => Ok(Target::LogRmse(v)),
            "rel-rmse" => Ok(Target::RelRmse(v)),
            "psnr" => Ok(Target::Psnr(v)),
            other => Err(format!(
                "target {s:?}: unknown metric {other:?} (use log-rmse, rel-rmse or psnr)"
            )),
        }
    }
}

/// A candidate model size.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Candidate {
    /// Specular lobes.
    pub lobes: usize,
    /// Values per factor table.
    pub nodes: usize,
}

impl Candidate {
    /// Its layout (`nodes` values per table).
    pub fn layout(&self) -> Layout {
        Layout::isotropic(self.nodes)
    }

    /// Its parameter count.
    pub fn params(&self) -> usize {
        self.layout().param_count(self.lobes)
    }
}

/// Every candidate, fewest parameters first.
pub fn candidates() -> Vec<Candidate> {
    let mut c: Vec<Candidate> = [30, 45, 90]
        .iter()
        .flat_map(|&nodes| (1..=3).map(move |lobes| Candidate { lobes, nodes }))
        .collect();
    c.sort_by_key(|c| (c.params(), c.lobes));
    c
}

/// One fitted candidate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// The candidate.
    pub candidate: Candidate,
    /// Its parameter count.
    pub params: usize,
    /// The target metric's value.
    pub value: f64,
    /// Fit seconds.
    pub seconds: f64,
}

/// Fit candidates in order until one meets the target; returns the index of
/// the chosen trial (the first that meets it, else the best of all) and
/// the trials. `fit` returns the candidate's scores and fit seconds.
pub fn smallest_meeting<E>(
    target: Target,
    mut fit: impl FnMut(Candidate) -> Result<(Scores, f64), E>,
) -> Result<(usize, bool, Vec<Trial>), E> {
    let mut trials = Vec::new();
    for c in candidates() {
        let (s, seconds) = fit(c)?;
        trials.push(Trial {
            candidate: c,
            params: c.params(),
            value: target.value(&s),
            seconds,
        });
        if target.met_by(&s) {
            return Ok((trials.len() - 1, true, trials));
        }
    }
    Ok((best(target, &trials), false, trials))
}

/// Fit every candidate within `budget` parameters; returns the index of the
/// one with the lowest error under `metric` (ties: fewer parameters).
pub fn best_within<E>(
    budget: usize,
    metric: Target,
    mut fit: impl FnMut(Candidate) -> Result<(Scores, f64), E>,
) -> Result<Option<(usize, Vec<Trial>)>, E> {
    let mut trials = Vec::new();
    for c in candidates().into_iter().filter(|c| c.params() <= budget) {
        let (s, seconds) = fit(c)?;
        trials.push(Trial {
            candidate: c,
            params: c.params(),
            value: metric.value(&s),
            seconds,
        });
    }
    Ok((!trials.is_empty()).then(|| (best(metric, &trials), trials)))
}

/// The best trial under the target's metric (the first of equals).
fn best(target: Target, trials: &[Trial]) -> usize {
    (0..trials.len())
        .min_by(|&a, &b| {
            target
                .badness(trials[a].value)
                .total_cmp(&target.badness(trials[b].value))
        })
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metrics(log: f64) -> Metrics {
        Metrics {
            samples: 1,
            max_theta_deg: 85.0,
            cos_rmse: 0.0,
            rel_cos_rmse: 0.0,
            log_rmse: log,
        }
    }

    #[test]
    fn candidates_run_from_156_to_822_parameters() {
        let p: Vec<usize> = candidates().iter().map(|c| c.params()).collect();
        assert_eq!(p, vec![156, 219, 231, 282, 324, 417, 456, 639, 822]);
    }

    #[test]
    fn target_stops_at_the_first_candidate_that_meets_it() {
        // Error falls with parameter count: 1/params.
        let fit = |c: Candidate| Ok::<_, ()>((Scores::from(metrics(1.0 / c.params() as f64)), 1.0));
        let (i, met, trials) = smallest_meeting(Target::LogRmse(1.0 / 300.0), fit).unwrap();
        assert!(met);
        assert_eq!(trials[i].params, 324);
        assert_eq!(trials.len(), 5);
        let (i, met, trials) = smallest_meeting(Target::LogRmse(1e-9), fit).unwrap();
        assert!(!met);
        assert_eq!(trials[i].params, 822);
        let (i, trials) = best_within(420, Target::LogRmse(0.0), fit)
            .unwrap()
            .unwrap();
        assert_eq!(trials[i].params, 417);
        assert!(best_within(100, Target::LogRmse(0.0), fit)
            .unwrap()
            .is_none());
    }

    #[test]
    fn psnr_targets_want_more_not_less() {
        let t = Target::Psnr(40.0);
        let s = |db: f64| Scores {
            metrics: metrics(0.0),
            render_psnr_db: Some(db),
        };
        assert!(t.met_by(&s(41.0)));
        assert!(!t.met_by(&s(39.0)));
        let fit = |c: Candidate| Ok::<_, ()>((s(c.params() as f64 / 10.0), 1.0));
        let (i, met, trials) = smallest_meeting(t, fit).unwrap();
        assert!(met);
        assert_eq!(trials[i].params, 417);
    }

    #[test]
    fn targets_parse_or_explain() {
        assert_eq!("log-rmse=0.01".parse::<Target>(), Ok(Target::LogRmse(0.01)));
        assert_eq!("rel-rmse=5e-2".parse::<Target>(), Ok(Target::RelRmse(0.05)));
        assert!("psnr"
            .parse::<Target>()
            .unwrap_err()
            .contains("METRIC=VALUE"));
        assert!("log-rmse=-1"
            .parse::<Target>()
            .unwrap_err()
            .contains("positive"));
        assert!("mse=1"
            .parse::<Target>()
            .unwrap_err()
            .contains("unknown metric"));
    }
}
