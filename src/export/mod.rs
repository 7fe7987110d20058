//! Exports of a fitted model for renderers.

pub mod shader;
