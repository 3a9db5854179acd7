//! Our BC6H KTX2 files checked by an outside KTX2 implementation: Don McCurdy's `ktx-parse`
//! (npm, pinned to 2.0.0 in tests/ktx2/package.json, driven by tests/ktx2/ktx2.mjs).
//!
//! (a) Files our `bc6h-ktx2` codec writes (UF16 and SF16, with and without mip chains, sizes
//! that are and are not multiples of 4) parse in ktx-parse with the header, level sizes and data
//! format descriptor the KTX 2.0 and Khronos Data Format specifications prescribe, and every
//! level's bytes equal the blocks our writer was given and the blocks our DDS writer stores for
//! the same image at the same effort (the DDS files are checked against imagecodecs elsewhere).
//! (b) Files ktx-parse's own serializer writes from our blocks (with a DFD it was given here)
//! read back in our reader with the same blocks and identical decoded pixels.
//! (c) The colour primaries: files written from images in BT.709, BT.2020, Display P3 and with
//! unspecified primaries carry the colorPrimaries value ktx-parse reads as 1, 4, 10 and 0, and
//! ktx-parse-written files with those values decode to those primaries in our reader.
//!
//! Set up with scripts/setup-reference-tools.sh (`npm ci` in tests/ktx2).
mod common;

use common::{require, run_ok, temp_dir, tool, Rng};
use hdrcodec::bc6h::{encode::EncodeOptions, encode_texture, read_dds, read_ktx2, Bc6hDdsCodec, Bc6hKtx2Codec};
use hdrcodec::core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, HdrImage, ImageCodec, Limits};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Vulkan `VK_FORMAT_BC6H_UFLOAT_BLOCK` / `VK_FORMAT_BC6H_SFLOAT_BLOCK` (Vulkan specification,
/// VkFormat; the header's vkFormat field in the KTX 2.0 specification). Not 131/132: those are
/// the BC1_RGB formats.
const VK_BC6H_UFLOAT: u32 = 143;
const VK_BC6H_SFLOAT: u32 = 144;

/// Bytes before the block data in a DDS file with the DX10 header: magic (4) + DDS_HEADER (124)
/// + DDS_HEADER_DXT10 (20) (Microsoft, "DDS file layout").
const DDS_DATA_OFFSET: usize = 4 + 124 + 20;

/// node and the directory holding ktx2.mjs with ktx-parse installed, if set up.
fn ktx_parse() -> Option<(PathBuf, PathBuf)> {
    let dir = common::workspace_root().join("tests/ktx2");
    let installed = dir.join("node_modules/ktx-parse/package.json").is_file();
    let node = require(tool("node"), "node (Node.js)")?;
    require(installed.then_some(()), "ktx-parse in tests/ktx2/node_modules (npm ci)")?;
    Some((node, dir))
}

/// ktx-parse's view of a KTX2 file, as `path=value` facts (see tests/ktx2/ktx2.mjs).
fn parse(node: &Path, dir: &Path, file: &Path) -> HashMap<String, String> {
    let out = run_ok(Command::new(node).current_dir(dir).arg("ktx2.mjs").arg("flat").arg(file));
    String::from_utf8(out.stdout)
        .expect("utf-8 output")
        .lines()
        .filter_map(|l| l.split_once('=').map(|(k, v)| (k.to_string(), v.to_string())))
        .collect()
}

fn get<'a>(facts: &'a HashMap<String, String>, key: &str) -> &'a str {
    facts.get(key).unwrap_or_else(|| panic!("ktx-parse reported no {key}"))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Size in bytes of a BC6H surface: 16 bytes per 4x4 block, partial blocks rounded up
/// (Microsoft "BC6H format"; KTX 2.0, "Level Index": byteLength of block-compressed levels).
fn blocks_bytes(w: u32, h: u32) -> usize {
    w.div_ceil(4) as usize * h.div_ceil(4) as usize * 16
}

/// A deterministic HDR test image: smooth gradients over several stops plus noise; negative
/// values too when `signed` (SF16 keeps them, UF16 clamps them to 0).
fn image(w: u32, h: u32, signed: bool, seed: u64) -> HdrImage {
    let mut rng = Rng(seed);
    let mut samples = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            for c in 0..3u32 {
                let t = (x as f32 + 1.0) / (w as f32 + 1.0) + (y as f32) / (h as f32 + 1.0) * (c as f32 + 1.0);
                let mut v = (t * 6.0 - 2.0).exp2() * (1.0 + rng.below(100) as f32 / 400.0);
                if signed && (x + 2 * y + c) % 5 == 0 {
                    v = -v;
                }
                samples.push(v);
            }
        }
    }
    HdrImage::new(w, h, Channels::Rgb, samples, ColorInfo::default()).expect("test image")
}

/// The primaries the files are labelled with, in turn, and the DFD colorPrimaries each must
/// carry (Khronos Data Format Specification 1.3, section 5.6, khr_df_primaries_e:
/// KHR_DF_PRIMARIES_UNSPECIFIED 0, BT709 1, BT2020 4, DISPLAYP3 10).
const PRIMARIES: [(ColorPrimaries, u32); 4] = [
    (ColorPrimaries::Bt709, 1),
    (ColorPrimaries::Bt2020, 4),
    (ColorPrimaries::DisplayP3, 10),
    (ColorPrimaries::Unspecified, 0),
];

/// (width, height, full mip chain, effort): 1x1, 5x3 and 13x7 (not multiples of 4), 64x64.
const CASES: [(u32, u32, bool, u8); 6] =
    [(1, 1, false, 1), (5, 3, false, 3), (5, 3, true, 2), (13, 7, true, 4), (64, 64, false, 1), (64, 64, true, 3)];

/// Levels of a full mip chain: floor(log2(max(w, h))) + 1 (KTX 2.0, "levelCount").
fn full_levels(w: u32, h: u32) -> usize {
    let mut n = 1;
    let mut m = w.max(h);
    while m > 1 {
        m /= 2;
        n += 1;
    }
    n
}

/// Checks ktx-parse's header, level index and DFD facts for a BC6H file whose DFD should say
/// `primaries` (a khr_df_primaries_e value); returns the number of DFD/header fields compared.
fn check_container(
    facts: &HashMap<String, String>,
    w: u32,
    h: u32,
    levels: usize,
    signed: bool,
    primaries: u32,
) -> usize {
    let vk = if signed { VK_BC6H_SFLOAT } else { VK_BC6H_UFLOAT };
    // KTX 2.0 header fields ("typeSize", "pixelWidth/Height/Depth", "layerCount", "faceCount",
    // "supercompressionScheme"): typeSize 1 for block-compressed formats; a 2D texture has
    // pixelDepth 0; a non-array texture layerCount 0; no cube map: faceCount 1; no
    // supercompression: scheme 0.
    let header = [
        ("vkFormat", vk.to_string()),
        ("typeSize", "1".into()),
        ("pixelWidth", w.to_string()),
        ("pixelHeight", h.to_string()),
        ("pixelDepth", "0".into()),
        ("layerCount", "0".into()),
        ("faceCount", "1".into()),
        ("levelCount", levels.to_string()),
        ("supercompressionScheme", "0".into()),
    ];
    // Khronos Data Format Specification 1.3, chapter "Khronos Basic Data Format Descriptor
    // Block" (the DFD that KTX 2.0's "Data Format Descriptor" section embeds), field by field:
    // vendorId KHRONOS (0), descriptorType BASICFORMAT (0), versionNumber 2 (KDF 1.3);
    // colorModel KHR_DF_MODEL_BC6H = 133 (its "BC6H" model section); colorPrimaries as the
    // image's (section 5.6, see PRIMARIES); transferFunction LINEAR = 1 (BC6H holds linear floats); flags 0; texelBlockDimension
    // stores each dimension - 1, so a 4x4x1x1 block is 3,3,0,0; bytesPlane0 = 16 (one 128-bit
    // block), planes 1-7 unused; one sample over bits 0..127: bitOffset 0, bitLength = bits - 1
    // = 127, channelType KHR_DF_CHANNEL_BC6H_COLOR (0) with the qualifier FLOAT (0x80), plus
    // SIGNED (0x40) for SF16; samplePosition 0; sampleLower/sampleUpper hold float bit
    // patterns for float samples: 0 (unsigned) or -1.0 = 0xBF800000 (signed), to 1.0 =
    // 0x3F800000 (the descriptors khr_df.h / the KDF give for BC6H UFLOAT and SFLOAT).
    let channel_type = 0x80 | if signed { 0x40 } else { 0 };
    let lower: u32 = if signed { 0xBF80_0000 } else { 0 };
    let dfd = [
        ("dfd.vendorId", "0".to_string()),
        ("dfd.descriptorType", "0".into()),
        ("dfd.versionNumber", "2".into()),
        ("dfd.colorModel", "133".into()),
        ("dfd.colorPrimaries", primaries.to_string()),
        ("dfd.transferFunction", "1".into()),
        ("dfd.flags", "0".into()),
        ("dfd.texelBlockDimension.0", "3".into()),
        ("dfd.texelBlockDimension.1", "3".into()),
        ("dfd.texelBlockDimension.2", "0".into()),
        ("dfd.texelBlockDimension.3", "0".into()),
        ("dfd.bytesPlane.0", "16".into()),
        ("dfd.samples.0.bitOffset", "0".into()),
        ("dfd.samples.0.bitLength", "127".into()),
        ("dfd.samples.0.channelType", channel_type.to_string()),
        ("dfd.samples.0.samplePosition.0", "0".into()),
        ("dfd.samples.0.samplePosition.1", "0".into()),
        ("dfd.samples.0.samplePosition.2", "0".into()),
        ("dfd.samples.0.samplePosition.3", "0".into()),
        ("dfd.samples.0.sampleLower", lower.to_string()),
        ("dfd.samples.0.sampleUpper", 0x3F80_0000u32.to_string()),
    ];
    for (key, want) in header.iter().chain(dfd.iter()) {
        assert_eq!(get(facts, key), want, "{key} of a {w}x{h} signed={signed} file");
    }
    for p in 1..8 {
        assert_eq!(get(facts, &format!("dfd.bytesPlane.{p}")), "0", "bytesPlane{p}");
    }
    assert!(!facts.contains_key("dfd.samples.1.bitLength"), "BC6H has exactly one sample");
    // KTX 2.0, "Level Index": without supercompression uncompressedByteLength = byteLength.
    for i in 0..levels {
        let (lw, lh) = ((w >> i).max(1), (h >> i).max(1));
        let need = blocks_bytes(lw, lh).to_string();
        assert_eq!(get(facts, &format!("levels.{i}.byteLength")), need, "level {i} ({lw}x{lh}) byteLength");
        assert_eq!(get(facts, &format!("levels.{i}.uncompressedByteLength")), need, "level {i} uncompressed");
    }
    assert!(!facts.contains_key(&format!("levels.{levels}.byteLength")), "more levels than levelCount");
    header.len() + dfd.len() + 7 + 2 * levels
}

#[test]
fn our_ktx2_files_parse_in_ktx_parse_and_its_files_read_back_in_ours() {
    let Some((node, dir)) = ktx_parse() else { return };
    let tmp = temp_dir("bc6h_ktx2_reference");
    let limits = Limits::default();
    let (mut files, mut levels_checked, mut bytes_checked, mut fields, mut pixels) = (0, 0, 0usize, 0, 0usize);
    let mut primaries_seen = Vec::new();
    for signed in [false, true] {
        for (case, &(w, h, mips, effort)) in CASES.iter().enumerate() {
            let mut img = image(w, h, signed, 0x6b74_7832 + case as u64);
            // Every label on each signedness: the samples are the same whatever the label.
            let (label, dfd_primaries) = PRIMARIES[(case + usize::from(signed)) % PRIMARIES.len()];
            img.color.primaries = label;
            let flag = |b: bool| if b { "true" } else { "false" };
            let settings = EncodeSettings::default()
                .with_effort(effort)
                .with_option("signed", flag(signed))
                .with_option("mips", flag(mips));
            let ktx = Bc6hKtx2Codec.encode(&img, &settings).expect("KTX2 encode");
            let dds = Bc6hDdsCodec.encode(&img, &settings).expect("DDS encode");
            // The blocks the writer was given: the same encoder run directly.
            let options = EncodeOptions { signed, effort, ..Default::default() };
            let tex = encode_texture(w, h, img.samples(), &options, mips).expect("encode_texture");
            assert_eq!(hdrcodec::bc6h::write_ktx2(&tex, label).unwrap(), ktx, "codec and write_ktx2 agree");

            let n = if mips { full_levels(w, h) } else { 1 };
            assert_eq!(tex.levels.len(), n);
            let name = format!("{w}x{h}_{}_{}", if signed { "sf16" } else { "uf16" }, if mips { "mips" } else { "1" });
            let ours = tmp.join(format!("ours_{name}.ktx2"));
            std::fs::write(&ours, &ktx).unwrap();
            let facts = parse(&node, &dir, &ours);
            fields += check_container(&facts, w, h, n, signed, dfd_primaries);
            assert_eq!(Bc6hKtx2Codec.decode(&ktx, &limits).unwrap().color.primaries, label, "{name}: ours read back");
            if !primaries_seen.contains(&dfd_primaries) {
                primaries_seen.push(dfd_primaries);
            }
            assert!(get(&facts, "keyValue.KTXwriter").starts_with("hdrcodec"), "KTXwriter key");

            // (a) every level as ktx-parse reads it = the blocks given = the DDS file's blocks.
            let total: usize = (0..n).map(|i| blocks_bytes((w >> i).max(1), (h >> i).max(1))).sum();
            assert_eq!(dds.len(), DDS_DATA_OFFSET + total, "DDS size for {name}");
            let mut pos = DDS_DATA_OFFSET;
            for (i, level) in tex.levels.iter().enumerate() {
                let len = blocks_bytes((w >> i).max(1), (h >> i).max(1));
                let dds_level = &dds[pos..pos + len];
                pos += len;
                let parsed = get(&facts, &format!("levels.{i}.hex"));
                assert_eq!(parsed, hex(level), "{name} level {i}: ktx-parse's bytes vs the blocks written");
                assert_eq!(parsed, hex(dds_level), "{name} level {i}: ktx-parse's bytes vs the DDS blocks");
                levels_checked += 1;
                bytes_checked += len;
            }
            files += 1;

            // (b) ktx-parse writes a file from our blocks with its own serializer.
            let mut args = vec![
                "ktx2.mjs".to_string(),
                "write".into(),
                tmp.join(format!("theirs_{name}.ktx2")).display().to_string(),
                (if signed { VK_BC6H_SFLOAT } else { VK_BC6H_UFLOAT }).to_string(),
                w.to_string(),
                h.to_string(),
                (signed as u8).to_string(),
                dfd_primaries.to_string(),
            ];
            for (i, level) in tex.levels.iter().enumerate() {
                let f = tmp.join(format!("{name}_level{i}.bin"));
                std::fs::write(&f, level).unwrap();
                args.push(f.display().to_string());
            }
            run_ok(Command::new(&node).current_dir(&dir).args(&args));
            let theirs_path = tmp.join(format!("theirs_{name}.ktx2"));
            let theirs = std::fs::read(&theirs_path).unwrap();
            // ktx-parse agrees that its file and ours hold the same container (its DFD was
            // filled in from the same specification sections).
            check_container(&parse(&node, &dir, &theirs_path), w, h, n, signed, dfd_primaries);
            let back = read_ktx2(&theirs, &limits).expect("our reader on ktx-parse's file");
            assert_eq!(back, tex, "{name}: blocks read back from ktx-parse's file");
            let dds_tex = read_dds(&dds, &limits).unwrap();
            for i in 0..n {
                let a = back.decode_level(i, &limits).unwrap();
                let b = dds_tex.decode_level(i, &limits).unwrap();
                assert_eq!(a.len(), b.len());
                assert!(
                    a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{name} level {i}: decoded pixels differ"
                );
                pixels += a.len() / 3;
            }
            let via_codec = Bc6hKtx2Codec.decode(&theirs, &limits).expect("codec decode of ktx-parse's file");
            assert_eq!(via_codec.color.primaries, label, "{name}: the primaries of ktx-parse's file");
            let via_dds = Bc6hDdsCodec.decode(&dds, &limits).unwrap();
            assert!(via_codec.samples().iter().zip(via_dds.samples()).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }
    eprintln!(
        "ktx-parse 2.0.0: {files} of our KTX2 files, {levels_checked} levels ({bytes_checked} bytes) identical to \
         the written and the DDS blocks, {fields} header/DFD/level fields as specified (colorPrimaries \
         {primaries_seen:?}); {files} ktx-parse-written files read back with {pixels} identical decoded pixels"
    );
    assert_eq!(files, 2 * CASES.len());
    primaries_seen.sort_unstable();
    assert_eq!(primaries_seen, [0, 1, 4, 10], "every label was checked");
}
