//! BC6H (BPTC float) GPU texture encoder and decoder, in DDS and KTX2 files (being written)
