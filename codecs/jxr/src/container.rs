//! The JPEG XR file container (T.832 Annex A): a TIFF-like IFD with the pixel-format GUID and
//! the offsets of the image and alpha codestreams.
