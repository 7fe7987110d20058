//! The rule every sampler's component selection shares.

/// Every component with mass is chosen with at least this probability
/// (before renormalisation), so the mixture pdf covers all of f.
pub const SELECTION_FLOOR: f64 = 0.01;
