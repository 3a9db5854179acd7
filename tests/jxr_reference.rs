//! hdrcodec-jxr against the JPEG XR references:
//! - the three corpus `.jxr` files and a matrix of streams jxrlib's JxrEncApp writes from
//!   corpus crops (half, float, RGBA with planar and interleaved alpha, 8- and 16-bit RGB,
//!   16- and 32-bit fixed point, 8/16-bit grey, grey half and float, BGR/BGRA, 565/555/101010;
//!   overlap 0/1/2, spatial and frequency order, sequential packets, tiles, trimmed flexbits,
//!   band truncation, 4:2:0, 4:2:2, Y-only, lossless and lossy) entropy-decode to exactly the
//!   coefficients the ITU reference software T.835 feeds its inverse transform. T.835 cannot
//!   be built in CI, so its coefficients are kept as digests ([`PlaneCoeffs::digest`]),
//!   computed on a developer's machine with T.835 1.32 (mloskot/jxr-refsoft) built with a
//!   print of the dequantized, predicted coefficients (`r_strip.c: dequantize_up_dclp`,
//!   `IPCT_level2_up2`);
//! - end to end (entropy decoding, the inverse transform, output formatting), every corpus
//!   file and matrix stream decodes to exactly jxrlib's samples (imagecodecs' `jpegxr_decode`,
//!   which calls jxrlib, in the pixel format's own layout, or JxrDecApp's TIFF for the formats
//!   imagecodecs converts: padded float, fixed point, 555/565/101010);
//! - the corpus files and a representative part of the matrix, patched to HD Photo 1.0
//!   codestreams (sub-version 0, jxrlib's legacy transform), also decode to exactly jxrlib's
//!   samples;
//! - `probe` agrees with jxrlib (imagecodecs) on size and channels;
//! - truncated and damaged corpus files give errors or images, never panics.

mod common;

use hdrcodec_core::{DecodeOptions, ImageCodec, Limits};
use hdrcodec_jxr::container::parse_container;
use hdrcodec_jxr::decoder::DIGEST_START;
use hdrcodec_jxr::{decode_coefficients, decode_raw, JxrCodec};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The digest of every plane of a file: primary, interleaved alpha, then planar alpha.
fn digest(file: &[u8], pool: hdrcodec_core::ThreadPool) -> u64 {
    let container = parse_container(file).unwrap();
    let options = DecodeOptions::new(Limits::default()).with_pool(pool);
    let c = decode_coefficients(container.image, &options).unwrap();
    let mut state = c.digest(DIGEST_START);
    if let Some(alpha) = container.alpha {
        state = decode_coefficients(alpha, &options).unwrap().digest(state);
    }
    state
}

/// T.835's digests of the corpus files.
const CORPUS: [(&str, u64); 3] = [
    ("GoldenGate_48bppRGBHalf_lossless.jxr", 0xb8e8_48f0_89a6_dc7e),
    ("StillLife_128bppRGBAFloat_q0.9.jxr", 0x6aae_1f6f_a9ea_b1e2),
    ("venice_sunset_1k_32bppRGBE_lossless.jxr", 0x6010_f167_70a7_62aa),
];

#[test]
fn corpus_coefficients_match_t835() {
    let Some(files) = common::corpus_files("jxr", "jxr") else { return };
    let names: Vec<String> = files.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    for (name, want) in CORPUS {
        assert!(names.iter().any(|n| n == name), "corpus file {name} is missing");
        let file = std::fs::read(files.iter().find(|p| p.ends_with(name)).unwrap()).unwrap();
        assert_eq!(digest(&file, hdrcodec_core::ThreadPool::single()), want, "{name}");
    }
}

/// Writes the crops the matrix encodes, as uncompressed TIFFs JxrEncApp reads, from the
/// corpus's GoldenGate (decoded by jxrlib through imagecodecs).
const CROPS: &str = r#"
import imagecodecs, numpy as np, struct, sys
out, src = sys.argv[1], sys.argv[2]
def write_tiff(path, arr):
    h, w, n = arr.shape
    dt = arr.dtype
    data = np.ascontiguousarray(arr).astype(dt.newbyteorder('<')).tobytes()
    kind = {'f': 3, 'i': 2}.get(dt.kind, 1)
    entries = [(256, 4, [w]), (257, 4, [h]), (258, 3, [dt.itemsize * 8] * n), (259, 3, [1]),
               (262, 3, [2 if n >= 3 else 1]), (273, 4, [0]), (277, 3, [n]), (278, 4, [h]),
               (279, 4, [len(data)]), (284, 3, [1]), (339, 3, [kind] * n)]
    if n == 4: entries.append((338, 3, [2]))
    entries.sort()
    extra = 8 + 2 + 12 * len(entries) + 4
    data_off = extra + 8 * n + 4
    entries = [(t, ty, [data_off] if t == 273 else v) for t, ty, v in entries]
    ifd = struct.pack('<H', len(entries)); tail = b''
    for tag, typ, vals in entries:
        size = len(vals) * (2 if typ == 3 else 4)
        if size <= 4:
            v = b''.join(struct.pack('<H' if typ == 3 else '<I', x) for x in vals).ljust(4, b'\0')
        else:
            v = struct.pack('<I', extra + len(tail)); tail += b''.join(struct.pack('<H', x) for x in vals)
        ifd += struct.pack('<HHI', tag, typ, len(vals)) + v
    body = (b'II*\0' + struct.pack('<I', 8) + ifd + struct.pack('<I', 0) + tail).ljust(data_off, b'\0') + data
    open(out + '/' + path, 'wb').write(body)
img = imagecodecs.jpegxr_decode(open(src, 'rb').read())
def crop(h, w, y=300, x=500): return np.ascontiguousarray(img[y:y+h, x:x+w])
ramp = lambda h, w: np.linspace(0, 1, h * w).reshape(h, w, 1).astype(np.float16)
write_tiff('half_100x72.tif', crop(72, 100))
write_tiff('half_17x5.tif', crop(5, 17))
write_tiff('half_1x1.tif', crop(1, 1))
write_tiff('half_200x130.tif', crop(130, 200, 100, 300))
write_tiff('float_100x72.tif', crop(72, 100).astype(np.float32))
write_tiff('halfa_100x72.tif', np.concatenate([crop(72, 100), ramp(72, 100)], axis=2))
write_tiff('floata_100x72.tif', np.concatenate([crop(72, 100), ramp(72, 100)], axis=2).astype(np.float32))
write_tiff('rgb8_100x72.tif', (np.clip(crop(72, 100).astype(np.float32), 0, 1) ** (1/2.2) * 255).astype(np.uint8))
write_tiff('rgb16_100x72.tif', (np.clip(crop(72, 100).astype(np.float32), 0, 1) * 65535).astype(np.uint16))
write_tiff('grayh_100x72.tif', np.ascontiguousarray(crop(72, 100)[:, :, 1:2]))
write_tiff('grayf_100x72.tif', np.ascontiguousarray(crop(72, 100)[:, :, 1:2].astype(np.float32)))
write_tiff('fixed16_100x72.tif', (np.clip(crop(72, 100).astype(np.float32), -3, 3) * 8192).astype(np.int16))
g8 = (np.clip(crop(72, 100).astype(np.float32), 0, 1) ** (1/2.2) * 255).astype(np.uint8)
g16 = (np.clip(crop(72, 100).astype(np.float32), 0, 1) * 65535).astype(np.uint16)
write_tiff('rgba8_100x72.tif', np.concatenate([g8, np.linspace(0, 255, 7200).reshape(72, 100, 1).astype(np.uint8)], axis=2))
write_tiff('rgba16_100x72.tif', np.concatenate([g16, np.linspace(0, 65535, 7200).reshape(72, 100, 1).astype(np.uint16)], axis=2))
write_tiff('fixed32_100x72.tif', (np.clip(crop(72, 100).astype(np.float32), -100, 100) * (1 << 24)).astype(np.int32))
write_tiff('gray8_100x72.tif', np.ascontiguousarray(g8[:, :, 1:2]))
write_tiff('gray16_100x72.tif', np.ascontiguousarray(g16[:, :, 1:2]))
"#;

/// A matrix stream without a T.835 digest (added since T.835 was last run): checked against
/// jxrlib's samples only.
const NO_T835: u64 = 0;

/// The matrix: name, input crop, JxrEncApp options, T.835's digest (or [`NO_T835`]).
const MATRIX: &[(&str, &str, &str, u64)] = &[
    ("h_default", "half_100x72", "-c 12", 0x7ca5_8acd_1cf7_6fdd),
    ("h_spatial", "half_100x72", "-c 12 -f", 0x7ca5_8acd_1cf7_6fdd),
    ("h_ol0", "half_100x72", "-c 12 -l 0", 0xa481_39cd_a1d8_3476),
    ("h_ol2", "half_100x72", "-c 12 -l 2", 0xb5d2_48b7_7184_5314),
    ("h_q03", "half_100x72", "-c 12 -q 0.3", 0x3e83_a1c2_0149_5b93),
    ("h_q07", "half_100x72", "-c 12 -q 0.7", 0xb817_e814_e5ad_614b),
    ("h_q09s", "half_100x72", "-c 12 -q 0.9 -f", 0xd8f8_b36d_6bc7_0979),
    ("h_q40", "half_100x72", "-c 12 -q 40", 0x61d7_d9d4_e336_6730),
    ("h_tiles", "half_100x72", "-c 12 -V 3 2 -H 2", 0x7ca5_8acd_1cf7_6fdd),
    ("h_tiles_sp", "half_100x72", "-c 12 -f -q 0.7 -V 3 2 -H 2", 0xb817_e814_e5ad_614b),
    ("h_tiles_seq", "half_100x72", "-c 12 -p -q 0.5 -U 2 3", 0x4a44_9d42_12c9_265c),
    ("h_trim", "half_100x72", "-c 12 -q 0.8 -F 5", 0xfee1_978a_fe9f_ebe6),
    ("h_trim_sp", "half_100x72", "-c 12 -q 0.8 -F 3 -f", 0xfee1_978a_fe9f_ebe6),
    ("h_s1", "half_100x72", "-c 12 -q 0.8 -s 1", 0xfee1_978a_fe9f_ebe6),
    ("h_s2", "half_100x72", "-c 12 -q 0.8 -s 2", 0x7b6c_902b_489f_de36),
    ("h_s3", "half_100x72", "-c 12 -q 0.8 -s 3", 0xa568_157c_9e1b_c16a),
    ("h_s2sp", "half_100x72", "-c 12 -q 0.8 -s 2 -f", 0x7b6c_902b_489f_de36),
    ("h_17x5", "half_17x5", "-c 12 -q 0.6", 0x8cf4_dbcc_0019_f091),
    ("h_1x1", "half_1x1", "-c 12", 0xcc5b_5685_e103_cfe8),
    ("h_big", "half_200x130", "-c 12 -q 0.4 -U 3 2", 0x822c_46e1_c22d_72c7),
    ("f_q09", "float_100x72", "-c 15 -q 0.9", 0xe294_9623_88aa_0a7e),
    ("f_lossless", "float_100x72", "-c 15", 0x1e0f_353b_d210_b01a),
    ("ha_planar", "halfa_100x72", "-c 25 -q 0.8 -Q 30", 0xe636_a66e_323b_ce57),
    ("ha_inter", "halfa_100x72", "-c 25 -a 3 -q 0.8 -Q 30", 0xe636_a66e_323b_ce57),
    ("ha_inter_sp", "halfa_100x72", "-c 25 -a 3 -q 0.6 -Q 10 -f", 0x4e89_0db1_144b_9343),
    ("fa_inter", "floata_100x72", "-c 28 -a 3 -q 0.9", 0xe1f7_0ea0_4217_e7b0),
    ("r8_420", "rgb8_100x72", "-c 9 -d 1 -q 0.6", 0xb897_30aa_4273_85ab),
    ("r8_422", "rgb8_100x72", "-c 9 -d 2 -q 0.6", 0x1013_b9d9_c33b_4f05),
    ("r8_q03", "rgb8_100x72", "-c 9 -q 0.3", 0x996a_bfbd_909d_51c6),
    ("r8_420sp", "rgb8_100x72", "-c 9 -d 1 -q 0.5 -f -l 2", 0x74c3_cad8_37ac_2dea),
    ("r8_422t", "rgb8_100x72", "-c 9 -d 2 -q 0.7 -V 2 -H 2 -l 2", 0x5da5_57c9_fb4c_8712),
    ("r8_y", "rgb8_100x72", "-c 9 -d 0 -q 0.7", 0x3a83_6333_d257_7719),
    ("r8_lossless", "rgb8_100x72", "-c 9", 0x7ea5_248f_f0d1_7362),
    ("r16", "rgb16_100x72", "-c 10 -q 0.8", 0xc0f9_1500_34cc_a7fa),
    ("g_half", "grayh_100x72", "-c 5 -q 0.7", 0x2fcf_28bc_bac7_6851),
    ("g_float", "grayf_100x72", "-c 8 -q 0.9", 0x736f_2853_3b61_95af),
    ("g_half_sp", "grayh_100x72", "-c 5 -q 0.5 -f -V 2 -H 2", 0x24ef_ef92_5a87_a8f7),
    ("fx16", "fixed16_100x72", "-c 11 -q 0.8", 0xf99f_9d1e_a66b_b3d2),
    ("fx16l", "fixed16_100x72", "-c 11", 0xbd11_85fc_15bd_1307),
    ("bgra8", "rgba8_100x72", "-c 22 -q 0.8 -a 3 -Q 20", 0x00fa_2c00_dc7d_6486),
    ("bgra8p", "rgba8_100x72", "-c 22 -q 0.8", 0x4885_1754_0845_3389),
    ("rgba16", "rgba16_100x72", "-c 23 -q 0.7 -a 3", 0xb6e6_567f_75ea_1b42),
    ("fx32", "fixed32_100x72", "-c 14 -q 0.9", 0x0c54_1fb0_89a6_228b),
    ("gray8", "gray8_100x72", "-c 2 -q 0.6", 0x0b8a_6a69_30ef_84a4),
    ("gray16", "gray16_100x72", "-c 3 -q 0.8", 0x47cc_5158_9db3_d8d7),
    ("r565", "rgb8_100x72", "-c 30 -q 0.9", 0x71fb_ea79_1324_3ab2),
    ("r555", "rgb8_100x72", "-c 29 -q 0.8", 0xd307_d6c3_50bf_df5c),
    ("r101010", "rgb16_100x72", "-c 31 -q 0.8", 0x9ddd_fe04_cd69_9bf4),
    ("bgr24", "rgb8_100x72", "-c 0 -q 0.7", 0xb351_316a_564f_8b2f),
    ("ha_s1", "halfa_100x72", "-c 25 -a 3 -q 0.8 -Q 30 -s 1", 0x1cd0_433f_b970_3d24),
    ("ha_s2", "halfa_100x72", "-c 25 -a 3 -q 0.8 -Q 30 -s 2", 0xdc78_9e50_e9e8_b6ec),
    ("ha_s3", "halfa_100x72", "-c 25 -a 3 -q 0.8 -Q 30 -s 3", 0xcb35_6393_0018_105e),
    ("ha_trim", "halfa_100x72", "-c 25 -a 3 -q 0.8 -Q 30 -F 3", 0x1cd0_433f_b970_3d24),
    ("ha_tiles", "halfa_100x72", "-c 25 -a 3 -q 0.6 -Q 20 -p -V 2 3 -H 2", 0x0e23_dfb4_dca8_0415),
    ("ha_tiles_sp", "halfa_100x72", "-c 25 -a 3 -q 0.6 -Q 20 -f -U 2 2 -F 2", 0xbca7_fb81_2ec6_6d25),
    ("r8_420_s2", "rgb8_100x72", "-c 9 -d 1 -q 0.5 -s 2", 0xfc65_1169_0070_c1a4),
    ("r8_422_tr", "rgb8_100x72", "-c 9 -d 2 -q 0.9 -F 4 -f", 0x7638_b75b_ebd7_840c),
    ("bgra_420", "rgba8_100x72", "-c 22 -d 1 -q 0.4 -a 3 -Q 40", 0x5643_9d3d_f010_5295),
    // Below quality 0.5 JxrEncApp codes the colour with two overlap stages and the planar
    // (lossless) alpha with one: each codestream is transformed with its own OVERLAP_MODE.
    ("ha_planar_ol2", "halfa_100x72", "-c 25 -q 0.3", NO_T835),
];

/// One generated stream: its name, T.835's digest, its path.
type Stream = (&'static str, u64, PathBuf);

/// Generates the matrix's streams with JxrEncApp into a temporary directory, once per test
/// run (the tests share them); `None` (skip, or panic in CI) without the venv, JxrEncApp or
/// the corpus.
fn matrix_streams() -> Option<(PathBuf, Vec<Stream>)> {
    static STREAMS: OnceLock<Option<(PathBuf, Vec<Stream>)>> = OnceLock::new();
    STREAMS.get_or_init(generate_matrix).clone()
}

fn generate_matrix() -> Option<(PathBuf, Vec<Stream>)> {
    let py = common::require(common::python(), "the reference venv (imagecodecs)")?;
    let enc = common::require(common::tool("JxrEncApp"), "JxrEncApp (Debian libjxr-tools)")?;
    let files = common::corpus_files("jxr", "jxr")?;
    let src = files.iter().find(|p| p.ends_with(CORPUS[0].0)).expect("the GoldenGate corpus file");
    let dir = common::temp_dir("jxr_matrix");
    common::run_python(&py, CROPS, &[dir.as_os_str(), src.as_os_str()]);
    let mut out = Vec::new();
    for &(name, input, args, want) in MATRIX {
        let jxr = dir.join(format!("{name}.jxr"));
        let mut cmd = Command::new(&enc);
        cmd.arg("-i").arg(dir.join(format!("{input}.tif"))).arg("-o").arg(&jxr).args(args.split(' '));
        common::run_ok(&mut cmd);
        out.push((name, want, jxr));
    }
    Some((dir, out))
}

#[test]
fn jxrenc_matrix_coefficients_match_t835() {
    let Some((_dir, streams)) = matrix_streams() else { return };
    let pool = hdrcodec_core::ThreadPool::new(2).unwrap();
    let mut bad = Vec::new();
    for (name, want, path) in &streams {
        let file = std::fs::read(path).unwrap();
        let got = digest(&file, hdrcodec_core::ThreadPool::single());
        if got != *want && *want != NO_T835 {
            bad.push(format!("{name}: {got:#018x}, T.835 {want:#018x}"));
        }
        // Tiles decoded in parallel give the same coefficients.
        assert_eq!(digest(&file, pool.clone()), got, "{name} on two threads");
    }
    assert!(bad.is_empty(), "coefficients differ from T.835's:\n{}", bad.join("\n"));
}

/// The stream that checks planar alpha's own overlap has it: colour with two overlap stages,
/// alpha with one (its samples are compared with jxrlib's with the rest of the matrix).
#[test]
fn planar_alpha_stream_has_its_own_overlap() {
    let Some((_dir, streams)) = matrix_streams() else { return };
    let (_, _, path) = streams.iter().find(|s| s.0 == "ha_planar_ol2").unwrap();
    let file = std::fs::read(path).unwrap();
    let c = parse_container(&file).unwrap();
    let overlap = |cs: &[u8]| hdrcodec_jxr::header::parse(cs).unwrap().image.overlap;
    assert_eq!((overlap(c.image), overlap(c.alpha.expect("planar alpha"))), (2, 1));
}

/// imagecodecs' (jxrlib's) shape of a decoded file: height, width, samples per pixel.
fn jxrlib_shape(py: &Path, path: &Path) -> (u32, u32, usize) {
    let script = "import imagecodecs, sys\na = imagecodecs.jpegxr_decode(open(sys.argv[1], 'rb').read())\n\
                  print(a.shape[0], a.shape[1], a.shape[2] if a.ndim == 3 else 1)";
    let out = common::run_python(py, script, &[path.as_os_str()]);
    let text = String::from_utf8(out.stdout).unwrap();
    let v: Vec<usize> = text.split_whitespace().map(|t| t.parse().unwrap()).collect();
    (v[0] as u32, v[1] as u32, v[2])
}

#[test]
fn probe_agrees_with_jxrlib() {
    let Some(py) = common::require(common::python(), "the reference venv (imagecodecs)") else { return };
    let Some(files) = common::corpus_files("jxr", "jxr") else { return };
    for path in &files {
        let file = std::fs::read(path).unwrap();
        assert!(JxrCodec.sniff(&file));
        let info = JxrCodec.probe(&file, &Limits::default()).unwrap();
        let (h, w, n) = jxrlib_shape(&py, path);
        assert_eq!((info.width, info.height), (w, h), "{}", path.display());
        // jxrlib gives RGBE as 4 bytes per pixel; everything else as its channels.
        if !path.to_string_lossy().contains("RGBE") {
            assert_eq!(info.channels.count(), n, "{}", path.display());
        }
    }
}

#[test]
fn damaged_corpus_files_never_panic() {
    let Some(files) = common::corpus_files("jxr", "jxr") else { return };
    let limits = Limits::fuzzing();
    for path in &files {
        let file = std::fs::read(path).unwrap();
        let cs = parse_container(&file).unwrap().image;
        // Truncations at 40 points, and byte flips (the crate's unit tests sweep every byte of small streams).
        let step = (cs.len() / 40).max(1);
        for n in (0..cs.len()).step_by(step) {
            assert!(decode_coefficients(&cs[..n], &DecodeOptions::new(limits.clone())).is_err());
        }
        let mut rng = common::Rng(cs.len() as u64 | 1);
        let mut bad = cs.to_vec();
        for _ in 0..20 {
            let at = rng.below(cs.len() as u32) as usize;
            bad[at] ^= 1 << rng.below(8);
            let _ = decode_coefficients(&bad, &DecodeOptions::new(limits.clone()));
            bad[at] = cs[at];
        }
        for n in (0..file.len()).step_by(file.len() / 10) {
            let _ = JxrCodec.probe(&file[..n], &limits);
            let _ = JxrCodec.decode(&file[..n], &limits);
        }
    }
}

/// How a stream's samples are compared with jxrlib's: imagecodecs' array as it is, the same
/// with our blue-first channels reordered, or the sample bytes of JxrDecApp's TIFF (the formats
/// imagecodecs converts: padded float, fixed point, 555/565/101010; a padding channel of ours
/// is dropped).
fn check_mode(name: &str) -> &'static str {
    match name {
        "bgra8" | "bgra8p" | "bgr24" | "bgra_420" => "bgr",
        "f_q09" | "f_lossless" | "fx16" | "fx16l" | "fx32" | "r565" | "r555" | "r101010" => "tif",
        _ => "ic",
    }
}

/// A Python function reading the samples of the uncompressed TIFFs JxrDecApp writes (width,
/// height, samples per pixel, the strips' bytes), for the comparison scripts.
const TIFF_SAMPLES_PY: &str = r#"
def tiff_samples(path):
    b = open(path, 'rb').read()
    off = struct.unpack('<I', b[4:8])[0]; n = struct.unpack('<H', b[off:off + 2])[0]
    tags = {}
    for i in range(n):
        t, ty, c, v = struct.unpack('<HHII', b[off + 2 + 12 * i:off + 14 + 12 * i]); tags[t] = (ty, c, v)
    def vals(t):
        ty, c, v = tags[t]; size = 2 if ty == 3 else 4
        if c * size <= 4: return [v & 0xffff if ty == 3 else v]
        return list(struct.unpack('<%d%s' % (c, 'H' if ty == 3 else 'I'), b[v:v + c * size]))
    data = b''.join(b[o:o + c] for o, c in zip(vals(273), vals(279)))
    return tags[256][2], tags[257][2], tags[277][2] & 0xffff, data
"#;

/// Compares our raw samples of each file with jxrlib's, in one Python run: returns the lines
/// it prints, one per file ("path differing-samples"). Modes: "ic" (imagecodecs), "bgr"
/// (imagecodecs, B and R swapped), "tif" (JxrDecApp's TIFF); with "+alpha" appended jxrlib's
/// samples must have four channels (else "no alpha" is printed).
fn jxrlib_raw_diffs(py: &Path, dec: &Path, pairs: &[(PathBuf, PathBuf, &str)]) -> Vec<String> {
    let script = &(r#"
import imagecodecs, numpy as np, struct, subprocess, sys
dec, args = sys.argv[1], sys.argv[2:]
"#
    .to_string()
        + TIFF_SAMPLES_PY
        + r#"
for jxr, raw, mode in zip(args[::3], args[1::3], args[2::3]):
    ours = open(raw, 'rb').read()
    # A '+alpha' mode: jxrlib must give four channels, so that alpha is compared too.
    mode, _, need_alpha = mode.partition('+')
    if mode == 'tif':
        subprocess.run([dec, '-i', jxr, '-o', raw + '.tif'], check=True, capture_output=True)
        w, h, spp, ref = tiff_samples(raw + '.tif')
        if need_alpha and spp != 4:
            print(jxr, 'no alpha'); continue
        if len(ours) != len(ref) and len(ours) * spp == len(ref) * (spp + 1):
            k = len(ours) // (w * h * (spp + 1))
            ours = b''.join(ours[i:i + k * spp] for i in range(0, len(ours), k * (spp + 1)))
        print(jxr, 'size' if len(ours) != len(ref) else sum(x != y for x, y in zip(ours, ref)))
        continue
    ref = imagecodecs.jpegxr_decode(open(jxr, 'rb').read())
    if need_alpha and (ref.ndim != 3 or ref.shape[2] != 4):
        print(jxr, 'no alpha'); continue
    if len(ref.tobytes()) != len(ours):
        print(jxr, 'size'); continue
    a = np.frombuffer(ours, dtype=ref.dtype).reshape(ref.shape)
    if mode == 'bgr':
        a = a[:, :, [2, 1, 0] + list(range(3, ref.shape[2]))]
    print(jxr, int((a != ref).sum()))
"#);
    let mut args: Vec<&std::ffi::OsStr> = vec![dec.as_os_str()];
    for (jxr, raw, mode) in pairs {
        args.extend([jxr.as_os_str(), raw.as_os_str(), std::ffi::OsStr::new(*mode)]);
    }
    let out = common::run_python(py, script, &args);
    String::from_utf8(out.stdout).unwrap().lines().map(str::to_string).collect()
}

/// What the end-to-end comparisons with jxrlib need: the reference venv (imagecodecs), its
/// JxrDecApp, the corpus files and the JxrEncApp matrix (`None`, said, when one is missing).
struct JxrlibCheck {
    py: PathBuf,
    dec: PathBuf,
    files: Vec<PathBuf>,
    dir: PathBuf,
    streams: Vec<Stream>,
}

impl JxrlibCheck {
    fn new() -> Option<Self> {
        let py = common::require(common::python(), "the reference venv (imagecodecs)")?;
        let dec = common::require(common::tool("JxrDecApp"), "JxrDecApp (Debian libjxr-tools)")?;
        let files = common::corpus_files("jxr", "jxr")?;
        let (dir, streams) = matrix_streams()?;
        Some(JxrlibCheck { py, dec, files, dir, streams })
    }

    /// Asserts that each (`.jxr`, our raw samples, check mode) gives jxrlib's samples.
    fn assert_same(&self, pairs: &[(PathBuf, PathBuf, &str)], what: &str) {
        let lines = jxrlib_raw_diffs(&self.py, &self.dec, pairs);
        assert_eq!(lines.len(), pairs.len(), "{lines:?}");
        let bad: Vec<&String> = lines.iter().filter(|l| !l.ends_with(" 0")).collect();
        assert!(bad.is_empty(), "{what} differ from jxrlib's:\n{bad:?}");
    }
}

#[test]
fn samples_match_jxrlib_end_to_end() {
    let Some(check) = JxrlibCheck::new() else { return };
    let (files, dir, streams) = (&check.files, &check.dir, &check.streams);
    let options = DecodeOptions::new(Limits::default());
    let mut pairs = Vec::new();
    let inputs = files
        .iter()
        .map(|p| (p.clone(), "ic"))
        .chain(streams.iter().map(|(name, _, path)| (path.clone(), check_mode(name))));
    for (path, mode) in inputs {
        let raw = decode_raw(&std::fs::read(&path).unwrap(), &options).unwrap();
        let raw_path = dir.join(format!("{}.ours.raw", path.file_name().unwrap().to_string_lossy()));
        std::fs::write(&raw_path, raw).unwrap();
        pairs.push((path, raw_path, mode));
    }
    check.assert_same(&pairs, "samples");
}

/// A representative part of the matrix (every internal format, alpha kind, overlap mode and
/// bitstream order; lossless, lossy with HP steps on both sides of 20, and without HP).
const HD_PHOTO_SUBSET: &[&str] = &[
    "h_ol2",
    "h_q03",
    "h_q40",
    "h_tiles_sp",
    "h_tiles_seq",
    "h_s2",
    "h_s3",
    "h_17x5",
    "h_big",
    "f_q09",
    "ha_planar",
    "ha_inter_sp",
    "fa_inter",
    "r8_420",
    "r8_422",
    "r8_420sp",
    "r8_422t",
    "r8_y",
    "r8_lossless",
    "r16",
    "g_half_sp",
    "fx16",
    "bgra_420",
    "gray8",
    "r8_420_s2",
    "r8_422_tr",
];

/// `file` as an HD Photo 1.0 file: the sub-version nibble of each codestream (primary and
/// planar alpha; the low half of the byte after `WMPHOTO\0`) cleared, so that jxrlib decodes
/// the same coefficients with its legacy transform.
fn as_hd_photo(file: &[u8]) -> Vec<u8> {
    let c = parse_container(file).unwrap();
    let starts: Vec<usize> =
        std::iter::once(c.image).chain(c.alpha).map(|cs| cs.as_ptr() as usize - file.as_ptr() as usize).collect();
    let mut out = file.to_vec();
    for at in starts {
        assert_eq!(&out[at..at + 8], b"WMPHOTO\0");
        assert_eq!(out[at + 8], 0x11, "version 1, sub-version 1 (soft tiles)");
        out[at + 8] = 0x10;
    }
    out
}

/// HD Photo 1.0 streams (sub-version 0, which no encoder at hand writes: matrix streams with
/// the nibble cleared) decode to exactly jxrlib's samples, whose legacy transform differs from
/// JPEG XR's (`hdrcodec_jxr::transform`'s `legacy` module).
#[test]
fn hd_photo_streams_match_jxrlib() {
    let Some(check) = JxrlibCheck::new() else { return };
    let (files, dir, streams) = (&check.files, &check.dir, &check.streams);
    let options = DecodeOptions::new(Limits::default());
    let mut pairs = Vec::new();
    // The corpus files too: full-size images, one with a planar alpha codestream.
    let corpus = files.iter().map(|p| (p.file_stem().unwrap().to_string_lossy().into_owned(), p.clone(), "ic"));
    let subset = HD_PHOTO_SUBSET.iter().map(|name| {
        let (_, _, path) = streams.iter().find(|(n, _, _)| n == name).expect("a matrix stream");
        (name.to_string(), path.clone(), check_mode(name))
    });
    for (name, path, mode) in corpus.chain(subset) {
        let original = std::fs::read(&path).unwrap();
        let file = as_hd_photo(&original);
        let hdp = dir.join(format!("{name}.hdp.jxr"));
        std::fs::write(&hdp, &file).unwrap();
        let raw = decode_raw(&file, &options).unwrap();
        // Lossless files without overlap aside, the operators change the samples.
        assert_ne!(raw, decode_raw(&original, &options).unwrap(), "{name}");
        let raw_path = dir.join(format!("{name}.hdp.ours.raw"));
        std::fs::write(&raw_path, raw).unwrap();
        pairs.push((hdp, raw_path, mode));
    }
    check.assert_same(&pairs, "HD Photo samples");
}

/// The family's shared contracts on real files: the registry picks JPEG XR for `.jxr`; `probe`
/// says what `decode` gives; `decode_into` fills a strided `f32` or `f16` buffer with the same
/// samples, within a budget smaller than the image; the budget is charged while decoding and
/// returned after.
#[test]
fn corpus_files_keep_the_family_contracts() {
    use hdrcodec_core::half::f16;
    use hdrcodec_core::sink::FrameBufMut;
    let Some(files) = common::corpus_files("jxr", "jxr") else { return };
    let registry = hdrcodec::registry();
    for path in &files {
        let file = std::fs::read(path).unwrap();
        let name = path.display().to_string();
        let codec = registry.for_input(path, &file).unwrap();
        assert_eq!(codec.name(), "jxr", "{name}");
        assert!(codec.can_encode());
        let info = codec.probe(&file, &Limits::default()).unwrap();
        let limits = Limits::default();
        let whole = codec.decode(&file, &limits).unwrap();
        assert_eq!(limits.in_use(), 0, "{name}: every charge returned");
        assert_eq!((info.width, info.height, info.channels), (whole.width(), whole.height(), whole.channels()));
        assert_eq!(info.color, whole.color, "{name}");
        let (w, h) = (whole.width() as usize, whole.height() as usize);
        let row_len = w * whole.channels().count();
        let stride = row_len + 3;
        let decoded = (w * h * whole.channels().count() * 4) as u64;
        // Decoding into the caller's buffer allocates bands of coefficients and samples (a
        // large part of these small images, a few dozen MB of a 40 MP one), not the image.
        let budget = Limits::default();
        let options = DecodeOptions::new(budget.clone());
        let mut f32_buf = vec![-7.0f32; stride * h];
        codec
            .decode_into(&file, &options, FrameBufMut::f32(&mut f32_buf, stride))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut f16_buf = vec![f16::from_f32(-7.0); stride * h];
        codec
            .decode_into(&file, &options, FrameBufMut::f16(&mut f16_buf, stride))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        for y in 0..h {
            let want = whole.row(y as u32);
            let got = &f32_buf[y * stride..y * stride + row_len];
            assert!(want.iter().zip(got).all(|(a, b)| a.to_bits() == b.to_bits()), "{name}: row {y}");
            assert!(f32_buf[y * stride + row_len..(y + 1) * stride].iter().all(|&v| v == -7.0), "{name}: padding");
            let halves = &f16_buf[y * stride..y * stride + row_len];
            assert!(
                want.iter().zip(halves).all(|(a, b)| f16::from_f32(*a).to_bits() == b.to_bits()),
                "{name}: f16 row {y}"
            );
        }
        let into_peak = budget.peak();
        let fresh = Limits::default();
        codec.decode(&file, &fresh).unwrap();
        // Less by the image, but for the band buffer a strided or f16 target needs.
        assert!(
            into_peak + decoded / 2 <= fresh.peak(),
            "{name}: decode_into held {into_peak} bytes at its peak, decode {} (image {decoded})",
            fresh.peak()
        );
    }
}

/// `file` with its container rewritten: the same pixel format and codestream, and
/// PTM_COLOR_INFO set to `ptm` (T.832 A.7.4; jxrlib neither reads nor writes it).
fn with_colour_info(file: &[u8], ptm: [u8; 4]) -> Vec<u8> {
    use hdrcodec_core::bytes::{ByteOrder, ByteWriter};
    use hdrcodec_core::tiff::{write_header, IfdWriter, MAGIC_JPEG_XR};
    use hdrcodec_jxr::container::tag;
    let c = parse_container(file).unwrap();
    assert!(c.alpha.is_none(), "a file without a planar alpha codestream");
    let mut w = ByteWriter::new(ByteOrder::Little);
    let link = write_header(&mut w, MAGIC_JPEG_XR);
    let mut ifd = IfdWriter::new();
    ifd.bytes(tag::PIXEL_FORMAT, &c.pixel_format_guid);
    ifd.bytes(tag::PTM_COLOR_INFO, &ptm);
    ifd.long(tag::IMAGE_OFFSET, 0);
    ifd.long(tag::IMAGE_BYTE_COUNT, c.image.len() as u32);
    let image_at = (8 + ifd.size() as usize).next_multiple_of(2);
    ifd.long(tag::IMAGE_OFFSET, image_at as u32);
    ifd.write(&mut w, link).unwrap();
    while w.len() < image_at {
        w.u8(0);
    }
    w.bytes(c.image);
    w.into_vec()
}

/// A PQ / BT.2020 file (the layout of HDR10 captures: 10-bit or 16-bit integer codes): the
/// decoded image says BT.2020 and its samples are jxrlib's codes through the ST 2084 EOTF, in
/// units of 80 cd/m². jxrlib's codes are ours (`samples_match_jxrlib_end_to_end`).
#[test]
fn ptm_color_info_pq_bt2020_decodes_to_absolute_linear_light() {
    use hdrcodec_core::transfer::PqTransfer;
    use hdrcodec_core::ColorPrimaries;
    let Some((_, streams)) = matrix_streams() else { return };
    let options = DecodeOptions::new(Limits::default());
    for (name, _, path) in streams.iter().filter(|(n, _, _)| ["r101010", "r16", "gray16"].contains(n)) {
        let file = with_colour_info(&std::fs::read(path).unwrap(), [9, 16, 9, 1]);
        let image = JxrCodec.decode_with(&file, &options).unwrap();
        assert_eq!((image.color.primaries, image.color.nits_per_unit), (ColorPrimaries::Bt2020, 80.0), "{name}");
        assert_eq!(
            JxrCodec.probe(&file, &Limits::default()).unwrap().color,
            image.color,
            "{name}: probe says what decode gives"
        );
        let raw = decode_raw(&file, &options).unwrap();
        let n = (image.width() * image.height()) as usize;
        // The codes of each pixel's R, G, B.
        let codes: Vec<[f64; 3]> = match *name {
            "r101010" => raw
                .chunks_exact(4)
                .map(|p| {
                    let v = u32::from_le_bytes(p.try_into().unwrap());
                    [0, 10, 20].map(|s| f64::from((v >> s) & 1023) / 1023.0)
                })
                .collect(),
            "r16" => raw
                .chunks_exact(6)
                .map(|p| [0, 2, 4].map(|i| f64::from(u16::from_le_bytes([p[i], p[i + 1]])) / 65535.0))
                .collect(),
            _ => raw.chunks_exact(2).map(|p| [f64::from(u16::from_le_bytes([p[0], p[1]])) / 65535.0; 3]).collect(),
        };
        assert_eq!(codes.len(), n, "{name}");
        let mut worst = 0.0f64;
        for (px, code) in image.samples().chunks_exact(3).zip(&codes) {
            for c in 0..3 {
                let want = PqTransfer::decode(code[c]) / 80.0;
                worst = worst.max((f64::from(px[c]) - want).abs() / want.max(1e-3));
            }
        }
        assert!(worst < 1e-5, "{name}: relative error {worst}");
        // Brighter than SDR: the colour crops' PQ codes reach far above 1.0 (80 cd/m²).
        if *name != "gray16" {
            assert!(image.samples().iter().any(|&v| v > 1.5), "{name}");
        }
    }
}

/// `file` with the container's SPATIAL_XFRM_PRIMARY (which JxrEncApp writes, as 0) set to `o`.
fn with_orientation(file: &[u8], o: u32) -> Vec<u8> {
    let mut file = file.to_vec();
    let ifd = u32::from_le_bytes(file[4..8].try_into().unwrap()) as usize;
    let n = usize::from(u16::from_le_bytes([file[ifd], file[ifd + 1]]));
    let entry = (0..n)
        .map(|i| ifd + 2 + 12 * i)
        .find(|&e| u16::from_le_bytes([file[e], file[e + 1]]) == 0xBC02)
        .expect("JxrEncApp writes SPATIAL_XFRM_PRIMARY");
    file[entry + 8..entry + 12].copy_from_slice(&o.to_le_bytes());
    file
}

/// The container's orientation is applied as jxrlib's library applies it: the flips (1-3) match
/// imagecodecs' `jpegxr_decode` (jxrlib's glue) sample for sample. jxrlib cannot rotate these
/// formats (JxrDecApp `-O 4..7` and imagecodecs fail on half, float and 8-bit RGB files), so
/// the rotations (4-7) are checked against the stored image rotated by 90° clockwise and then
/// flipped (T.832's SPATIAL_XFRM; `core::sink::Orientation`'s own test checks the mapping).
#[test]
fn container_orientation_is_applied() {
    let Some(py) = common::require(common::python(), "the reference venv (imagecodecs)") else { return };
    let Some((dir, streams)) = matrix_streams() else { return };
    let (_, _, path) = streams.iter().find(|(n, _, _)| *n == "h_q07").unwrap();
    let file = std::fs::read(path).unwrap();
    let options = DecodeOptions::new(Limits::default());
    let stored = JxrCodec.decode_with(&file, &options).unwrap();
    let (w, h) = (stored.width() as usize, stored.height() as usize);
    let at = |x: usize, y: usize| &stored.samples()[(y * w + x) * 3..(y * w + x) * 3 + 3];
    for o in 1..8u32 {
        let oriented = with_orientation(&file, o);
        let image = JxrCodec.decode_with(&oriented, &options).unwrap();
        let info = JxrCodec.probe(&oriented, &Limits::default()).unwrap();
        assert_eq!((info.width, info.height), (image.width(), image.height()), "orientation {o}");
        let (ow, oh) = (image.width() as usize, image.height() as usize);
        assert_eq!((ow, oh), if o >= 4 { (h, w) } else { (w, h) }, "orientation {o}");
        for v in 0..oh {
            for u in 0..ow {
                let (u0, v0) = (if o & 2 != 0 { ow - 1 - u } else { u }, if o & 1 != 0 { oh - 1 - v } else { v });
                // Before the flips: rotated (source x = v0, y = h-1-u0) or not.
                let want = if o >= 4 { at(v0, h - 1 - u0) } else { at(u0, v0) };
                assert_eq!(
                    &image.samples()[(v * ow + u) * 3..(v * ow + u) * 3 + 3],
                    want,
                    "orientation {o} at {u},{v}"
                );
            }
        }
        if o < 4 {
            // jxrlib's glue applies the flips: its half samples, as f32, are ours.
            let out = dir.join(format!("oriented{o}.jxr"));
            std::fs::write(&out, &oriented).unwrap();
            let script = "import imagecodecs, sys, numpy as np\n\
                a = imagecodecs.jpegxr_decode(open(sys.argv[1], 'rb').read())\n\
                sys.stdout.buffer.write(np.ascontiguousarray(a[:, :, :3]).astype(np.float32).tobytes())\n";
            let res = common::run_python(&py, script, &[out.as_os_str()]);
            let theirs: Vec<f32> =
                res.stdout.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
            assert!(theirs == image.samples(), "orientation {o}: jxrlib's glue gives other samples");
        }
    }
}

/// Reduced-resolution and region decodes against JxrDecApp (`-T 2`, `-T 4`, `-r`, and `-T 2`
/// with `-r`) on a representative subset of the matrix and the corpus files: half, float,
/// RGBA half (interleaved and planar alpha), RGBE, 8- and 16-bit RGB, grey half, OL 0/1/2,
/// spatial and frequency order, tiles (soft, sequential packets), 4:2:0 and 4:2:2, trimmed
/// flexbits, an odd size (17x5). The sample bytes of JxrDecApp's TIFF must equal ours.
#[test]
fn reduced_and_region_decodes_match_jxrdecapp() {
    use hdrcodec_jxr::{decode_raw_with, JxrDecodeRequest, Rect, Resolution};
    let Some(py) = common::require(common::python(), "the reference venv (imagecodecs)") else { return };
    let Some(dec) = common::require(common::tool("JxrDecApp"), "JxrDecApp (Debian libjxr-tools)") else { return };
    let Some(files) = common::corpus_files("jxr", "jxr") else { return };
    let Some((dir, streams)) = matrix_streams() else { return };
    let subset = [
        "h_default",
        "h_spatial",
        "h_ol0",
        "h_ol2",
        "h_q03",
        "h_tiles_sp",
        "h_tiles_seq",
        "h_trim_sp",
        "h_17x5",
        "h_big",
        "f_q09",
        "ha_inter",
        "ha_planar",
        "ha_planar_ol2",
        "ha_inter_sp",
        "r8_420",
        "r8_420sp",
        "r8_422t",
        "r16",
        "g_half",
        "rgba16",
    ];
    let mut inputs: Vec<(String, PathBuf)> =
        streams.iter().filter(|(n, _, _)| subset.contains(n)).map(|(n, _, p)| (n.to_string(), p.clone())).collect();
    inputs.extend(files.iter().map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), p.clone())));
    let options = DecodeOptions::new(Limits::default());
    // (JxrDecApp arguments, our request); regions as JxrDecApp's `-r top left height width`.
    let region = |y, x, height, width| Some(Rect { x, y, width, height });
    let mut args: Vec<std::ffi::OsString> = vec![dec.into_os_string()];
    for (name, path) in &inputs {
        let small = name == "h_17x5";
        let requests = [
            ("-T 2", JxrDecodeRequest { region: None, resolution: Resolution::Quarter }),
            // JxrDecApp's -T 4 of images under 16 rows differs (codecs/jxr/README.md).
            if small {
                ("-T 2 -r 1 0 1 4", JxrDecodeRequest { region: region(1, 0, 1, 4), resolution: Resolution::Quarter })
            } else {
                ("-T 4", JxrDecodeRequest { region: None, resolution: Resolution::Sixteenth })
            },
            (
                if small { "-r 1 2 3 10" } else { "-r 3 7 50 61" },
                JxrDecodeRequest {
                    region: if small { region(1, 2, 3, 10) } else { region(3, 7, 50, 61) },
                    resolution: Resolution::Full,
                },
            ),
            (
                if small { "-T 2 -r 0 1 2 3" } else { "-T 2 -r 1 2 10 20" },
                JxrDecodeRequest {
                    region: if small { region(0, 1, 2, 3) } else { region(1, 2, 10, 20) },
                    resolution: Resolution::Quarter,
                },
            ),
        ];
        let file = std::fs::read(path).unwrap();
        // JxrDecApp's full-resolution `-r` of these is not the crop of its own whole decode
        // (checked: the region's edge rows or columns of 4:2:0 / 4:2:2 chroma are
        // interpolated from inside the region only); ours is the crop, which the unit tests
        // check, so they are left out here.
        let not_a_crop = ["r8_420sp", "r8_422t"].contains(&name.as_str());
        for (i, (decapp, request)) in requests.iter().enumerate() {
            if not_a_crop && request.resolution == Resolution::Full {
                continue;
            }
            let raw = decode_raw_with(&file, &options, request).unwrap_or_else(|e| panic!("{name} {decapp}: {e}"));
            let raw_path = dir.join(format!("{name}.req{i}.raw"));
            std::fs::write(&raw_path, raw).unwrap();
            args.extend([path.clone().into_os_string(), raw_path.into_os_string(), (*decapp).into()]);
        }
    }
    let script = &(r#"
import struct, subprocess, sys
dec, args = sys.argv[1], sys.argv[2:]
"#
    .to_string()
        + TIFF_SAMPLES_PY
        + r#"
for jxr, raw, opts in zip(args[::3], args[1::3], args[2::3]):
    subprocess.run([dec, '-i', jxr, '-o', raw + '.tif'] + opts.split(), check=True, capture_output=True)
    w, h, spp, ref = tiff_samples(raw + '.tif')
    ours = open(raw, 'rb').read()
    if len(ours) != len(ref) and len(ours) * spp == len(ref) * (spp + 1):
        k = len(ours) // (w * h * (spp + 1))
        ours = b''.join(ours[i:i + k * spp] for i in range(0, len(ours), k * (spp + 1)))
    print(jxr, opts, 'size' if len(ours) != len(ref) else sum(x != y for x, y in zip(ours, ref)))
"#);
    let refs: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
    let out = common::run_python(&py, script, &refs);
    let lines: Vec<String> = String::from_utf8(out.stdout).unwrap().lines().map(str::to_string).collect();
    assert_eq!(lines.len(), (args.len() - 1) / 3, "{lines:?}");
    let bad: Vec<&String> = lines.iter().filter(|l| !l.ends_with(" 0")).collect();
    assert!(bad.is_empty(), "reduced or region samples differ from JxrDecApp's:\n{bad:#?}");
}

/// A synthetic HDR picture for the encoder: smooth ramps over five decades, a hard edge, a
/// patch of noise and negative values (scRGB can hold them).
fn encoder_test_image(width: u32, height: u32, seed: u64) -> hdrcodec_core::HdrImage {
    let mut s = seed | 1;
    let mut noise = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut samples = Vec::with_capacity((width * height * 3) as usize);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (x as f32 / width as f32, y as f32 / height as f32);
            let base = 10f32.powf(5.0 * u - 2.0) * (0.5 + v);
            let edge = if x > width / 2 && y < height / 3 { 20.0 } else { 1.0 };
            let n = if x < width / 4 && y > height / 2 { noise() } else { 0.0 };
            samples.extend_from_slice(&[base * edge + n, base * 0.7 + n * 3.0, base * (1.3 - v) * edge - 0.01 * u]);
        }
    }
    let mut image =
        hdrcodec_core::HdrImage::new(width, height, hdrcodec_core::Channels::Rgb, samples, Default::default()).unwrap();
    // scRGB's unit: the samples go into the file as they are.
    image.color.nits_per_unit = 80.0;
    image
}

/// Files our encoder writes (half and float, lossless and lossy, the three overlap modes,
/// sizes that are and are not whole macroblocks) decode in jxrlib to exactly the samples our
/// decoder gives; lossless half files give back the input's half bit patterns. RGBA images
/// (planar alpha, lossless or lossy) too, alpha included; and the other stored formats
/// ([`encode_other_formats`]).
#[test]
fn jxrlib_decodes_our_encoded_files_as_we_do() {
    use hdrcodec_jxr::encoder::{encode, EncodeOptions, SampleFormat};
    use hdrcodec_jxr::transform::OverlapMode;
    let Some(check) = JxrlibCheck::new() else { return };
    let dir = check.dir.join("encoded");
    std::fs::create_dir_all(&dir).unwrap();
    let options = DecodeOptions::new(Limits::default());
    let mut pairs = Vec::new();
    for (w, h) in [(37u32, 23u32), (96, 64), (161, 50)] {
        let image = encoder_test_image(w, h, u64::from(w * h));
        for format in [SampleFormat::Half, SampleFormat::Float] {
            for quality in [100u8, 90, 60, 20] {
                for overlap in [None, Some(OverlapMode::None), Some(OverlapMode::Two)] {
                    // Tiles of 32 pixels on the wider images.
                    let tile_mbs = if w > 64 { 2 } else { 0 };
                    // Luminance-adaptive HP quantizers (several sets per tile), except at 60.
                    let adaptive = quality != 60;
                    let opts = EncodeOptions {
                        quality,
                        overlap,
                        format,
                        tile_mbs,
                        adaptive,
                        alpha_quality: 100,
                        target_bpp: None,
                        ..EncodeOptions::default()
                    };
                    let (file, _) = encode(&image, &opts, &hdrcodec_core::ThreadPool::single()).unwrap();
                    let name = format!("{w}x{h}_{format:?}_q{quality}_{overlap:?}");
                    let raw = decode_raw(&file, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
                    if quality == 100 && format == SampleFormat::Half {
                        let want: Vec<u8> = image
                            .samples()
                            .iter()
                            .flat_map(|&v| half::f16::from_f32(v).to_bits().to_le_bytes())
                            .collect();
                        assert!(raw == want, "{name}: a lossless half file does not give the input back");
                    }
                    let path = dir.join(format!("{name}.jxr"));
                    std::fs::write(&path, &file).unwrap();
                    let raw_path = dir.join(format!("{name}.ours.raw"));
                    std::fs::write(&raw_path, raw).unwrap();
                    // imagecodecs converts padded float; JxrDecApp's TIFF has the samples.
                    let mode = if format == SampleFormat::Float { "tif" } else { "ic" };
                    pairs.push((path, raw_path, mode));
                }
            }
        }
    }
    // RGBA: alpha as a planar alpha codestream; lossless alpha (the default) under lossless
    // and lossy colour, and lossy alpha; with tiles on the wider image.
    for (w, h) in [(37u32, 23u32), (161, 50)] {
        let image = with_test_alpha(&encoder_test_image(w, h, u64::from(w * h) + 1));
        for format in [SampleFormat::Half, SampleFormat::Float] {
            for (quality, alpha_quality) in [(100u8, 100u8), (60, 100), (90, 60), (20, 20)] {
                let tile_mbs = if w > 64 { 2 } else { 0 };
                // Adaptive colour HP quantizers (the default); alpha always has one set.
                let opts = EncodeOptions {
                    quality,
                    overlap: None,
                    format,
                    tile_mbs,
                    adaptive: true,
                    alpha_quality,
                    target_bpp: None,
                    ..EncodeOptions::default()
                };
                let (file, report) = encode(&image, &opts, &hdrcodec_core::ThreadPool::single()).unwrap();
                assert!(report.notes.is_empty(), "{:?}", report.notes);
                let name = format!("{w}x{h}_{format:?}_rgba_q{quality}_a{alpha_quality}");
                let raw = decode_raw(&file, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
                let bytes = if format == SampleFormat::Half { 2 } else { 4 };
                assert_eq!(raw.len(), (w * h) as usize * 4 * bytes, "{name}: four channels");
                if quality == 100 && format == SampleFormat::Half {
                    let want: Vec<u8> =
                        image.samples().iter().flat_map(|&v| half::f16::from_f32(v).to_bits().to_le_bytes()).collect();
                    assert!(raw == want, "{name}: a lossless half RGBA file does not give the input back");
                }
                let path = dir.join(format!("{name}.jxr"));
                std::fs::write(&path, &file).unwrap();
                let raw_path = dir.join(format!("{name}.ours.raw"));
                std::fs::write(&raw_path, raw).unwrap();
                let mode = if format == SampleFormat::Float { "tif+alpha" } else { "ic+alpha" };
                pairs.push((path, raw_path, mode));
            }
        }
    }
    pairs.extend(encode_other_formats(&dir, &options));
    check.assert_same(&pairs, "our encoded files");
}

/// The encoder's chroma subsampling, bitstream order, band and flexbit-trimming options, with
/// tiles and each overlap mode: jxrlib decodes every file to exactly our decoder's samples.
/// A small matrix of small images (each option at least twice, in both orders where it
/// matters); lossless frequency-order files give back the input.
#[test]
fn jxrlib_decodes_our_encoder_options_as_we_do() {
    use hdrcodec_jxr::encoder::{encode, BitstreamOrder, EncodeOptions, SampleFormat, Subsampling};
    use hdrcodec_jxr::header::{Bands, ClrFmt};
    use hdrcodec_jxr::transform::OverlapMode;
    use BitstreamOrder::{Frequency, Spatial};
    let Some(check) = JxrlibCheck::new() else { return };
    let dir = check.dir.join("encoded_options");
    std::fs::create_dir_all(&dir).unwrap();
    let options = DecodeOptions::new(Limits::default());
    let (s444, s422, s420) = (Subsampling::Yuv444, Subsampling::Yuv422, Subsampling::Yuv420);
    let (ol0, ol1, ol2) = (Some(OverlapMode::None), Some(OverlapMode::One), Some(OverlapMode::Two));
    // (size, subsampling, order, bands, trim, quality, overlap, tile in macroblocks, float, alpha)
    #[allow(clippy::type_complexity)]
    let cases: &[(
        (u32, u32),
        Subsampling,
        BitstreamOrder,
        Bands,
        u8,
        u8,
        Option<OverlapMode>,
        usize,
        bool,
        bool,
    )] = &[
        ((37, 23), s420, Spatial, Bands::All, 0, 60, ol1, 0, false, false),
        ((96, 64), s420, Spatial, Bands::All, 0, 20, ol2, 2, false, false),
        ((161, 50), s420, Frequency, Bands::All, 0, 40, ol2, 3, false, false),
        ((37, 23), s422, Spatial, Bands::All, 0, 90, ol0, 0, false, false),
        ((96, 64), s422, Frequency, Bands::All, 0, 30, ol2, 2, true, false),
        ((161, 50), s422, Spatial, Bands::All, 0, 70, ol1, 3, false, false),
        ((96, 64), s444, Frequency, Bands::All, 0, 100, ol1, 2, false, false),
        ((37, 23), s444, Frequency, Bands::All, 0, 90, ol0, 0, true, false),
        ((161, 50), s444, Frequency, Bands::All, 0, 60, ol2, 2, false, true),
        ((96, 64), s444, Spatial, Bands::NoFlexbits, 0, 90, ol1, 2, false, false),
        ((96, 64), s420, Frequency, Bands::NoFlexbits, 0, 60, ol2, 0, false, false),
        ((161, 50), s444, Frequency, Bands::NoHighpass, 0, 80, ol1, 3, false, false),
        ((37, 23), s422, Spatial, Bands::NoHighpass, 0, 50, ol2, 0, false, false),
        ((96, 64), s444, Spatial, Bands::DcOnly, 0, 90, ol0, 2, true, false),
        ((161, 50), s420, Frequency, Bands::DcOnly, 0, 60, ol2, 2, false, false),
        ((96, 64), s444, Spatial, Bands::All, 3, 95, ol1, 2, false, false),
        ((161, 50), s420, Frequency, Bands::All, 2, 90, ol2, 3, false, false),
    ];
    let mut pairs = Vec::new();
    for (i, &((w, h), subsampling, order, bands, trim, quality, overlap, tile_mbs, float, alpha)) in
        cases.iter().enumerate()
    {
        let mut image = encoder_test_image(w, h, u64::from(w * h) + i as u64);
        if alpha {
            image = with_test_alpha(&image);
        }
        let format = if float { SampleFormat::Float } else { SampleFormat::Half };
        let opts = EncodeOptions {
            quality,
            overlap,
            format,
            tile_mbs,
            subsampling,
            order,
            bands,
            trim_flexbits: trim,
            alpha_quality: 70,
            ..EncodeOptions::default()
        };
        let (file, _) = encode(&image, &opts, &hdrcodec_core::ThreadPool::new(2).unwrap()).unwrap();
        let name = format!("{i:02}_{w}x{h}_{subsampling:?}_{order:?}_{bands:?}_t{trim}_q{quality}_{format:?}");
        let container = hdrcodec_jxr::container::parse_container(&file).unwrap();
        let cs = hdrcodec_jxr::header::parse(container.image).unwrap();
        let fmt = match subsampling {
            Subsampling::Yuv444 => ClrFmt::Yuv444,
            Subsampling::Yuv422 => ClrFmt::Yuv422,
            Subsampling::Yuv420 => ClrFmt::Yuv420,
        };
        assert_eq!((cs.primary.clr_fmt, cs.primary.bands), (fmt, bands), "{name}");
        assert_eq!(cs.image.frequency_mode, order == Frequency, "{name}");
        assert_eq!(cs.image.trim_flexbits, trim > 0, "{name}");
        let raw = decode_raw(&file, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
        if quality == 100 && !float && !alpha {
            let want: Vec<u8> =
                image.samples().iter().flat_map(|&v| half::f16::from_f32(v).to_bits().to_le_bytes()).collect();
            assert!(raw == want, "{name}: a lossless half file does not give the input back");
        }
        let path = dir.join(format!("{name}.jxr"));
        std::fs::write(&path, &file).unwrap();
        let raw_path = dir.join(format!("{name}.ours.raw"));
        std::fs::write(&raw_path, raw).unwrap();
        let mode = match (float, alpha) {
            (false, false) => "ic",
            (true, false) => "tif",
            (false, true) => "ic+alpha",
            (true, true) => "tif+alpha",
        };
        pairs.push((path, raw_path, mode));
    }
    check.assert_same(&pairs, "our files with encoder options");
}

/// Explicit quantizers (`EncodeOptions::quantizers`, `--opt qp=`). At JxrEncApp's settings
/// (its quantizers read from its files of the matrix, its overlap, frequency order, one
/// quantizer set) our files of the same crops carry the same quantizers, are at most 1%
/// larger than JxrEncApp's and at most 10% smaller (our encoder zeroes HP blocks not worth
/// their bits, which JxrEncApp codes: 4% at `-q` 0.3) and decode within 0.3 dB of its
/// PU21-PSNR; and files with quantizers of every CHANNEL_MODE per band, adaptive sets above
/// them, tiles, half and float, decode in jxrlib to exactly our samples.
#[test]
fn jxrlib_decodes_our_explicit_quantizers_as_we_do() {
    use hdrcodec_core::metrics::pu21_psnr;
    use hdrcodec_jxr::encoder::{encode, BitstreamOrder, EncodeOptions, Quantizers, SampleFormat};
    use hdrcodec_jxr::transform::OverlapMode;
    let Some(check) = JxrlibCheck::new() else { return };
    let dir = check.dir.join("encoded_qp");
    std::fs::create_dir_all(&dir).unwrap();
    let options = DecodeOptions::new(Limits::default());
    let pool = hdrcodec_core::ThreadPool::new(2).unwrap();
    let stream = |name: &str| {
        let (_, _, path) = check.streams.iter().find(|(n, _, _)| *n == name).unwrap();
        std::fs::read(path).unwrap()
    };
    let decode = |file: &[u8]| JxrCodec.decode(file, &Limits::default()).unwrap();
    let mut pairs = Vec::new();
    let mut push = |name: String, file: &[u8], mode: &'static str| {
        let path = dir.join(format!("{name}.jxr"));
        std::fs::write(&path, file).unwrap();
        let raw_path = dir.join(format!("{name}.ours.raw"));
        std::fs::write(&raw_path, decode_raw(file, &options).unwrap_or_else(|e| panic!("{name}: {e}"))).unwrap();
        pairs.push((path, raw_path, mode));
    };
    // Equal settings: the lossless streams are the crops, exactly.
    for (theirs, crop, format, mode) in [
        ("h_q03", "h_default", SampleFormat::Half, "ic"),
        ("h_q07", "h_default", SampleFormat::Half, "ic"),
        ("f_q09", "f_lossless", SampleFormat::Float, "tif"),
    ] {
        let (file, input) = (stream(theirs), decode(&stream(crop)));
        let quantizers = Quantizers::of_file(&file).unwrap().expect("JxrEncApp's quantizers are uniform");
        let overlap = match parse_container(&file).map(|c| hdrcodec_jxr::header::parse(c.image).unwrap().image.overlap)
        {
            Ok(0) => OverlapMode::None,
            Ok(1) => OverlapMode::One,
            _ => OverlapMode::Two,
        };
        let opts = EncodeOptions {
            quantizers: Some(quantizers),
            overlap: Some(overlap),
            order: BitstreamOrder::Frequency,
            adaptive: false,
            format,
            ..EncodeOptions::default()
        };
        let (ours, _) = encode(&input, &opts, &pool).unwrap();
        assert_eq!(Quantizers::of_file(&ours).unwrap(), Some(quantizers), "{theirs}");
        let size = ours.len() as f64 / file.len() as f64;
        let (p_ours, p_theirs) =
            (pu21_psnr(&input, &decode(&ours)).unwrap(), pu21_psnr(&input, &decode(&file)).unwrap());
        eprintln!(
            "{theirs}: {quantizers:?}: ours {} bytes, {p_ours:.3} dB; JxrEncApp's {} bytes, {p_theirs:.3} dB",
            ours.len(),
            file.len()
        );
        assert!((0.9..1.01).contains(&size), "{theirs}: ours {} bytes, JxrEncApp's {}", ours.len(), file.len());
        assert!((p_ours - p_theirs).abs() < 0.3, "{theirs}: PU21-PSNR {p_ours} against JxrEncApp's {p_theirs}");
        push(format!("equal_{theirs}"), &ours, mode);
    }
    // CHANNEL_MODE 2, 1 and 0 in the bands, adaptive sets above the quantizers given, tiles.
    let jxrencapp = Quantizers::parse("97,118,120,109,137,144").unwrap();
    let mixed = Quantizers::parse("30,30,30,40,52,52,36,36,44").unwrap();
    let cases = [
        ((96, 64), jxrencapp, false, 0, false, BitstreamOrder::Spatial),
        ((161, 50), mixed, true, 3, false, BitstreamOrder::Frequency),
        ((37, 23), mixed, false, 0, true, BitstreamOrder::Spatial),
        ((96, 64), Quantizers::parse("12,20,28,16,24,40").unwrap(), true, 2, true, BitstreamOrder::Frequency),
    ];
    for (i, ((w, h), quantizers, adaptive, tile_mbs, float, order)) in cases.into_iter().enumerate() {
        let image = encoder_test_image(w, h, 7 * u64::from(w * h) + i as u64);
        let format = if float { SampleFormat::Float } else { SampleFormat::Half };
        let opts = EncodeOptions {
            quantizers: Some(quantizers),
            adaptive,
            tile_mbs,
            format,
            order,
            ..EncodeOptions::default()
        };
        let (file, _) = encode(&image, &opts, &pool).unwrap();
        push(
            format!("{i:02}_{w}x{h}_{format:?}_{order:?}_a{adaptive}_t{tile_mbs}"),
            &file,
            if float { "tif" } else { "ic" },
        );
    }
    check.assert_same(&pairs, "our files with explicit quantizers");
}

/// The other stored formats of our encoder (RGBE, fixed point, padded half, 8-, 16- and
/// 10-bit codes of sRGB, PQ and linear light; RGBA in the formats that have alpha), lossless
/// and lossy, one tile and tiles: writes each file and our decoder's samples into `dir` and
/// returns them with the way jxrlib's samples are read (imagecodecs, or JxrDecApp's TIFF for
/// the formats imagecodecs converts or refuses: fixed point, 64bppRGBHalf, 101010).
fn encode_other_formats(dir: &Path, options: &DecodeOptions) -> Vec<(PathBuf, PathBuf, &'static str)> {
    use hdrcodec_jxr::encoder::{encode, BitstreamOrder, EncodeOptions, SampleFormat, Subsampling};
    use hdrcodec_jxr::header::Bands;
    use hdrcodec_jxr::output::SampleTransfer;
    let formats = [
        (SampleFormat::Rgbe, "ic"),
        (SampleFormat::Fixed, "tif"),
        (SampleFormat::HalfPadded, "tif"),
        (SampleFormat::Rgb8(SampleTransfer::Srgb), "ic"),
        (SampleFormat::Rgb16(SampleTransfer::Pq), "ic"),
        (SampleFormat::Rgb16(SampleTransfer::Linear), "ic"),
        (SampleFormat::Rgb101010(SampleTransfer::Pq), "tif"),
    ];
    let rgba = [
        (SampleFormat::Fixed, "tif+alpha"),
        (SampleFormat::Rgb8(SampleTransfer::Srgb), "bgr+alpha"),
        (SampleFormat::Rgb16(SampleTransfer::Pq), "ic+alpha"),
    ];
    // Formats crossed with the codestream options (subsampling, order, bands, trimming, tiles),
    // at quality 60 on the larger image: (format, mode, alpha, options).
    let (freq, s420, s422) = (BitstreamOrder::Frequency, Subsampling::Yuv420, Subsampling::Yuv422);
    let o = EncodeOptions { quality: 60, ..EncodeOptions::default() };
    let (srgb8, pq16, pq10) = (
        SampleFormat::Rgb8(SampleTransfer::Srgb),
        SampleFormat::Rgb16(SampleTransfer::Pq),
        SampleFormat::Rgb101010(SampleTransfer::Pq),
    );
    let crossed = [
        (srgb8, "ic", false, EncodeOptions { subsampling: s420, order: freq, ..o.clone() }),
        (pq16, "ic+alpha", true, EncodeOptions { subsampling: s422, bands: Bands::NoHighpass, ..o.clone() }),
        (SampleFormat::Rgbe, "ic", false, EncodeOptions { subsampling: s420, order: freq, tile_mbs: 2, ..o.clone() }),
        (SampleFormat::Fixed, "tif", false, EncodeOptions { order: freq, bands: Bands::NoFlexbits, ..o.clone() }),
        (pq10, "tif", false, EncodeOptions { subsampling: s420, trim_flexbits: 3, ..o.clone() }),
        (SampleFormat::HalfPadded, "tif", false, EncodeOptions { subsampling: s420, ..o.clone() }),
        (srgb8, "bgr+alpha", true, EncodeOptions { order: freq, bands: Bands::DcOnly, ..o.clone() }),
    ];
    let mut pairs = Vec::new();
    // Encodes `image`, keeps the file and our decoder's samples in `dir` under `name`.
    let mut keep = |name: String, image: &hdrcodec_core::HdrImage, opts: &EncodeOptions, mode: &'static str| {
        let (file, _) = encode(image, opts, &hdrcodec_core::ThreadPool::single()).unwrap();
        let name = name.replace(['(', ')'], "_");
        let raw = decode_raw(&file, options).unwrap_or_else(|e| panic!("{name}: {e}"));
        let path = dir.join(format!("{name}.jxr"));
        std::fs::write(&path, &file).unwrap();
        let raw_path = dir.join(format!("{name}.ours.raw"));
        std::fs::write(&raw_path, raw).unwrap();
        pairs.push((path, raw_path, mode));
    };
    let rgb = encoder_test_image(161, 50, 161 * 50 + 3);
    let with_alpha = with_test_alpha(&rgb);
    for (i, (format, mode, alpha, opts)) in crossed.into_iter().enumerate() {
        let image = if alpha { &with_alpha } else { &rgb };
        keep(format!("crossed{i}_{format:?}"), image, &EncodeOptions { format, ..opts }, mode);
    }
    for (w, h) in [(37u32, 23u32), (161, 50)] {
        // Samples from 0.01 to 30 000 scRGB units: every format clips some (counted).
        let rgb = encoder_test_image(w, h, u64::from(w * h) + 2);
        let with_alpha = with_test_alpha(&rgb);
        let cases = formats.iter().map(|&(f, m)| (f, m, &rgb)).chain(rgba.iter().map(|&(f, m)| (f, m, &with_alpha)));
        for (format, mode, image) in cases {
            for quality in [100u8, 60] {
                let tile_mbs = if w > 64 { 2 } else { 0 };
                let opts = EncodeOptions { quality, format, tile_mbs, ..EncodeOptions::default() };
                let alpha = if mode.ends_with("alpha") { "_rgba" } else { "" };
                keep(format!("{w}x{h}_{format:?}{alpha}_q{quality}"), image, &opts, mode);
            }
        }
    }
    pairs
}

/// `image` with an alpha channel: opaque on the left third, a ramp from 0 to 1 with a
/// transparent hole and noise elsewhere (edges, flat areas and texture for the quantizers).
fn with_test_alpha(image: &hdrcodec_core::HdrImage) -> hdrcodec_core::HdrImage {
    let (w, h) = (image.width(), image.height());
    let samples = image
        .samples()
        .chunks(3)
        .enumerate()
        .flat_map(|(i, p)| {
            let (x, y) = (i as u32 % w, i as u32 / w);
            let a = if x < w / 3 {
                1.0
            } else if (x / 8 + y / 8) % 5 == 0 {
                0.0
            } else {
                ((x + 2 * y) as f32 / (w + 2 * h) as f32 + ((x * 7919 + y * 104_729) % 97) as f32 / 970.0).min(1.0)
            };
            [p[0], p[1], p[2], a]
        })
        .collect();
    hdrcodec_core::HdrImage::new(w, h, hdrcodec_core::Channels::Rgba, samples, image.color.clone()).unwrap()
}
