//! Alternating weighted least squares (AWLS) for the shared-factor model.
//!
//! Split as in argmin: [`state`] holds the working factors and per-sample
//! caches, [`updates`] and [`g_update`] are the element updates one sweep is
//! made of, [`executor`] loops sweeps until convergence and reports each one
//! to [`Observer`]s. Every update minimises the objective exactly over the
//! entries it changes (or, for G, keeps the best of the cubic's real roots
//! and the bound, and only if it lowers the objective), so the objective
//! never rises.
//!
//! Determinism: every parallel sum is taken over fixed-size chunks whose
//! partial results are added in chunk order, and entries updated in
//! parallel share no sample, so results are bit-for-bit identical for any
//! number of threads.

mod avx;
mod chunked;
pub mod diffuse;
pub mod duo;
pub mod executor;
pub mod g2_update;
pub mod g_update;
pub(crate) mod g_work;
pub mod gauge;
pub mod gauss_newton;
mod gram;
pub mod init;
pub mod kernels;
mod options;
pub mod separable;
pub mod state;
pub mod updates;

pub(crate) use chunked::{chunked_sum, chunked_sum_mut, CHUNK};
pub use executor::{Executor, FitResult, Observer, Stage, StageRecord, SweepReport};
pub use g_work::GPassStats;
pub use options::{
    DiffuseKind, FitOptions, GMethod, SolverError, CG_ITERATIONS, INDEPENDENT_CHANNELS, MAX_LOBES,
};
pub use state::Factors;
