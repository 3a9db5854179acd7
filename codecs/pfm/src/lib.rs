//! Portable float map (PFM) reading and writing for hdrcodec (being written)
