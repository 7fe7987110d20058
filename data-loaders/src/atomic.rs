//! Atomic writes (see the loaders work).
