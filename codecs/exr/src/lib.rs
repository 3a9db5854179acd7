//! OpenEXR reading and writing for hdrcodec, through the exr crate (being written)
