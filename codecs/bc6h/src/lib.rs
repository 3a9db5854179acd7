//! BC6H (BPTC float) GPU texture codec (being written).
pub mod encode;
