//! Radiance RGBE / XYZE (.hdr, .pic) codec (being written)
