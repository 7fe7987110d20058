//! MERL .binary tables (see the loaders work).
pub struct MerlTable;
