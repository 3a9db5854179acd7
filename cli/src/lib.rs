//! `hdrcodec-cli`: what the `hdrcodec` command line tool adds on top of the library: the bench
//! engine ([`bench`]), the batch engine ([`batch`]), the project's generated corpus ([`corpus`]), the rate-distortion
//! and speed plots ([`plot`]), the bench's Markdown report ([`report`]), the bench's HDR10 AV1 rows ([`video_bench`]), the shared corpus of real images ([`real_corpus`]), decoding's peak memory ([`memory`]), the tables' layout ([`text_table`]) and `compare`'s ΔE ITP heat map ([`heatmap`]). Kept out of the `hdrcodec` facade so that a program embedding the codecs pulls no
//! clap, plotters, png or serde.
#![forbid(unsafe_code)]

pub mod batch;
pub mod bench;
pub mod conversion;
pub mod corpus;
pub mod equal_quality;
pub mod heatmap;
pub mod jxrlib;
pub mod libultrahdr;
pub mod memory;
pub mod peers;
pub mod plot;
pub mod real_corpus;
pub mod report;
pub mod text_table;
pub mod video_bench;
