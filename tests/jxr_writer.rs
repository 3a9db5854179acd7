//! The JPEG XR header and container writers against real files: each corpus file, and tiled
//! streams JxrEncApp writes (frequency and spatial order, band-major and tile-major packets,
//! dropped packets), is taken apart with `parse_container` and `header::parse` and put back
//! together with `write_codestream` and `write_container`. The rewritten file must decode to
//! the same bytes as the original, with our decoder and (when it is installed; in CI it must
//! be) with jxrlib's JxrDecApp.

mod common;

use hdrcodec_core::{DecodeOptions, Limits};
use hdrcodec_jxr::container::{parse_container, write_container, ContainerMeta};
use hdrcodec_jxr::decode_raw;
use hdrcodec_jxr::header::{self, write_codestream};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The packets of a codestream in index-table order. A packet runs to the next packet start
/// in the file (the index order need not be the file order: JxrEncApp's default stores all DC
/// packets first, then LP, HP and FLEX) or to the end of the codestream. An entry at an offset
/// an earlier entry already has is a packet jxrlib dropped (written as the escape 0xFF, read
/// as offset 0): it stays empty, which `write_codestream` writes as the escape again.
fn packets(codestream: &[u8], cs: &header::Codestream) -> Vec<Vec<u8>> {
    let mut starts = cs.packets.clone();
    starts.sort_unstable();
    starts.dedup();
    let mut seen = HashSet::new();
    cs.packets
        .iter()
        .map(|&at| {
            if !seen.insert(at) {
                return Vec::new();
            }
            let end = starts.iter().copied().find(|&s| s > at).unwrap_or(codestream.len() as u64);
            codestream[at as usize..end as usize].to_vec()
        })
        .collect()
}

/// What a rewrite went through, so that the tests can check that the cases they are meant for
/// occur.
#[derive(Default)]
struct Seen {
    /// Packets jxrlib dropped (escaped index entries).
    dropped: usize,
    /// Codestreams whose packets are not stored in index-table order.
    out_of_order: usize,
    /// Codestreams without an index table (one spatial tile: the explicit profile stamp).
    no_index_table: usize,
}

/// Re-writes one codestream from its parsed headers and its packets, and checks that the
/// headers read back unchanged.
fn rewrite_codestream(codestream: &[u8], what: &str, seen: &mut Seen) -> Vec<u8> {
    let cs = header::parse(codestream).unwrap_or_else(|e| panic!("{what}: {e}"));
    let packets = packets(codestream, &cs);
    seen.dropped += packets.iter().filter(|p| p.is_empty()).count();
    seen.out_of_order += usize::from(!cs.packets.is_sorted());
    seen.no_index_table += usize::from(!cs.image.index_table);
    let out =
        write_codestream(&cs.image, &cs.primary, cs.alpha.as_ref(), &packets).unwrap_or_else(|e| panic!("{what}: {e}"));
    let again = header::parse(&out).unwrap();
    assert_eq!((&again.image, &again.primary, &again.alpha), (&cs.image, &cs.primary, &cs.alpha), "{what}");
    assert_eq!(again.packets.len(), cs.packets.len(), "{what}");
    for (i, (p, &at)) in packets.iter().zip(&again.packets).enumerate() {
        assert_eq!(&out[at as usize..at as usize + p.len()], &p[..], "{what}: packet {i}");
    }
    out
}

/// Re-writes a whole file: both codestreams, and the container with the original's metadata.
fn rewrite(file: &[u8], what: &str, seen: &mut Seen) -> Vec<u8> {
    let c = parse_container(file).unwrap_or_else(|e| panic!("{what}: {e}"));
    let image = rewrite_codestream(c.image, what, seen);
    let alpha = c.alpha.map(|a| rewrite_codestream(a, &format!("{what} (planar alpha)"), seen));
    let cs = header::parse(c.image).unwrap();
    let meta = ContainerMeta {
        icc: c.icc_profile.map(<[u8]>::to_vec),
        xmp: c.xmp.map(<[u8]>::to_vec),
        ptm_color_info: c.ptm_color_info,
        resolution: c.resolution.unwrap_or(ContainerMeta::default().resolution),
    };
    let width = c.width.unwrap_or(cs.image.width);
    let height = c.height.unwrap_or(cs.image.height);
    let out = write_container(c.pixel_format, width, height, &image, alpha.as_deref(), &meta).unwrap();
    let back = parse_container(&out).unwrap();
    assert_eq!(back.pixel_format, c.pixel_format, "{what}");
    assert_eq!(
        (back.width, back.height, back.resolution),
        (Some(width), Some(height), c.resolution.or(back.resolution))
    );
    assert_eq!(back.image, &image[..]);
    assert_eq!(back.alpha, alpha.as_deref());
    out
}

/// Our decoder's bytes for `file`.
fn ours(file: &[u8]) -> Vec<u8> {
    decode_raw(file, &DecodeOptions::new(Limits::default())).unwrap()
}

/// JxrDecApp's TIFF of `jxr` (written to `tif`), as bytes.
fn jxrdecapp(dec: &Path, jxr: &Path, tif: &Path) -> Vec<u8> {
    common::run_ok(Command::new(dec).arg("-i").arg(jxr).arg("-o").arg(tif));
    std::fs::read(tif).unwrap()
}

/// Checks one original file and its rewrite: same bytes from our decoder, and from JxrDecApp
/// when it is given.
fn check(file: &[u8], name: &str, dir: &Path, dec: Option<&Path>, seen: &mut Seen) {
    let again = rewrite(file, name, seen);
    assert!(ours(&again) == ours(file), "{name}: our decoder's output of the rewritten file differs");
    if let Some(dec) = dec {
        let stem = name.trim_end_matches(".jxr");
        let (a, b) = (dir.join(format!("{stem}.jxr")), dir.join(format!("{stem}_rewritten.jxr")));
        std::fs::write(&a, file).unwrap();
        std::fs::write(&b, &again).unwrap();
        let want = jxrdecapp(dec, &a, &dir.join(format!("{stem}.tif")));
        let got = jxrdecapp(dec, &b, &dir.join(format!("{stem}_rewritten.tif")));
        assert!(got == want, "{name}: JxrDecApp's output of the rewritten file differs");
    }
}

fn decoder() -> Option<PathBuf> {
    common::require(common::tool("JxrDecApp"), "JxrDecApp (Debian libjxr-tools); only our decoder is compared")
}

#[test]
fn rewritten_corpus_files_decode_the_same() {
    let Some(files) = common::corpus_files("jxr", "jxr") else { return };
    assert!(!files.is_empty(), "no .jxr corpus files");
    let dec = decoder();
    let dir = common::temp_dir("jxr_writer_corpus");
    let mut seen = Seen::default();
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        check(&std::fs::read(path).unwrap(), &name, &dir, dec.as_deref(), &mut seen);
    }
    // StillLife's planar alpha codestream has a FLEX packet jxrlib dropped (escaped entry).
    if files.iter().any(|p| p.ends_with("StillLife_128bppRGBAFloat_q0.9.jxr")) {
        assert!(seen.dropped > 0, "no dropped packet was rewritten");
    }
}

/// Tiled streams from JxrEncApp (the corpus files are single tiles): GoldenGate decoded by
/// JxrDecApp and re-encoded with tiles in frequency order (band-major and tile-major packets)
/// and in spatial order, with trimmed flexbits and dropped bands, and one spatial tile without
/// an index table.
#[test]
fn rewritten_tiled_jxrencapp_streams_decode_the_same() {
    let Some(dec) = decoder() else { return };
    let Some(enc) = common::require(common::tool("JxrEncApp"), "JxrEncApp (Debian libjxr-tools)") else { return };
    let Some(files) = common::corpus_files("jxr", "jxr") else { return };
    let Some(src) = files.iter().find(|p| p.ends_with("GoldenGate_48bppRGBHalf_lossless.jxr")) else {
        assert!(!common::in_ci(), "the GoldenGate corpus file is missing");
        return;
    };
    let dir = common::temp_dir("jxr_writer_tiles");
    let tif = dir.join("source.tif");
    common::run_ok(Command::new(&dec).arg("-i").arg(src).arg("-o").arg(&tif));
    let variants = [
        ("freq_band_major", "-q 0.8 -U 3 2"),
        ("freq_tile_major", "-q 0.8 -U 3 2 -p"),
        ("spatial", "-q 0.7 -U 2 3 -f"),
        ("uneven_trim", "-q 0.9 -V 20 30 -H 10 -F 3 -l 2"),
        ("lossless_tiles", "-U 2 2"),
        ("no_highpass", "-q 0.8 -U 2 2 -s 2"),
        ("dc_only_spatial", "-q 0.8 -U 2 2 -s 3 -f"),
        ("spatial_one_tile", "-q 0.8 -f"),
    ];
    let mut seen = Seen::default();
    for (name, args) in variants {
        let jxr = dir.join(format!("enc_{name}.jxr"));
        let mut cmd = Command::new(&enc);
        cmd.arg("-i").arg(&tif).arg("-o").arg(&jxr).arg("-c").arg("12").args(args.split(' '));
        common::run_ok(&mut cmd);
        check(&std::fs::read(&jxr).unwrap(), name, &dir, Some(&dec), &mut seen);
    }
    // JxrEncApp's default (progressive) layout stores packets band-major, not in index order.
    assert!(seen.out_of_order > 0, "every stream's packets were in index order");
    assert!(seen.no_index_table > 0, "every stream had an index table");
}
