//! BC6H (BPTC float) GPU texture codec: bit-exact decoder, format tables, DDS and KTX2 files.

pub mod encode;
pub mod modes;
