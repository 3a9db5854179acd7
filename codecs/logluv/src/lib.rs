//! LogL16, LogLuv24 and LogLuv32 pixel encodings and LogLuv TIFF files (being written)
