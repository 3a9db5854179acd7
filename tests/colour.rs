//! Issue 9's "Done means" for colour: BT.2020 images go through BC6H and PFM without a gamut
//! conversion (the same bytes as the same samples labelled BT.709) and score like BT.709 ones.
//! Also KTX2, which records BT.2020: the same blocks, only the DFD's colorPrimaries differs.

use hdrcodec::core::{ColorPrimaries, EncodeSettings, HdrImage, ImageCodec, ThreadPool};
use hdrcodec_cli::bench::{self, Config, Input};

/// The generated BT.2020 scene: pure BT.2020 primaries and secondaries, far outside BT.709.
fn bt2020_ramps() -> HdrImage {
    let img = hdrcodec_cli::corpus::scene("bt2020-ramps").expect("the scene exists").image;
    assert_eq!(img.color.primaries, ColorPrimaries::Bt2020);
    img
}

/// The same samples labelled `primaries`.
fn labelled(img: &HdrImage, primaries: ColorPrimaries) -> HdrImage {
    let mut out = img.clone();
    out.color.primaries = primaries;
    out
}

fn codec(name: &str) -> std::sync::Arc<dyn ImageCodec> {
    hdrcodec::registry().by_name(name).unwrap()
}

/// No note says a conversion happened ("... the samples were converted to X").
fn no_conversion(notes: &[String], what: &str) {
    assert!(notes.iter().all(|n| !n.contains("were converted") && !n.contains("as if")), "{what}: {notes:?}");
}

#[test]
fn bt2020_goes_through_bc6h_and_pfm_without_a_gamut_conversion() {
    let img = bt2020_ramps();
    let as709 = labelled(&img, ColorPrimaries::Bt709);
    let settings = EncodeSettings::default().with_effort(0);
    for name in ["bc6h", "pfm"] {
        let c = codec(name);
        let (bytes, notes) = hdrcodec::encode_for(c.as_ref(), &img, &settings).unwrap();
        let (bytes709, notes709) = hdrcodec::encode_for(c.as_ref(), &as709, &settings).unwrap();
        assert!(bytes == bytes709, "{name}: BT.2020 and BT.709-labelled samples give different files");
        no_conversion(&notes, name);
        no_conversion(&notes709, name);
        // The one note says the samples were stored as they are.
        assert_eq!(notes.len(), 1, "{name}: {notes:?}");
        assert!(notes[0].contains("the BT.2020 samples are stored as they are"), "{name}: {notes:?}");
        // The check means something: converting to BT.709 (as before) gives another file.
        let convert = settings.clone().with_option("primaries", "bt709");
        let (converted, _) = hdrcodec::encode_for(c.as_ref(), &img, &convert).unwrap();
        assert!(converted != bytes, "{name}: an explicit conversion changes the file");
        // Read back: the samples (PFM) or the codec's own approximation of them (BC6H),
        // unspecified.
        let back = c.decode(&bytes, &Default::default()).unwrap();
        assert_eq!(back.color.primaries, ColorPrimaries::Unspecified);
        if name == "pfm" {
            assert_eq!(back.samples(), img.samples());
        }
    }
    // KTX2 records BT.2020: the same blocks as the BT.709 label, only colorPrimaries differs
    // (4 against 1, KDF 1.3 section 5.6), and it reads back BT.2020.
    let ktx2 = codec("bc6h-ktx2");
    let (bytes, notes) = hdrcodec::encode_for(ktx2.as_ref(), &img, &settings).unwrap();
    let (bytes709, _) = hdrcodec::encode_for(ktx2.as_ref(), &as709, &settings).unwrap();
    assert!(notes.is_empty(), "{notes:?}");
    let differ: Vec<usize> = (0..bytes.len()).filter(|&i| bytes[i] != bytes709[i]).collect();
    assert_eq!(bytes.len(), bytes709.len());
    assert_eq!(differ.len(), 1, "only the DFD's colorPrimaries byte differs: {differ:?}");
    assert_eq!((bytes[differ[0]], bytes709[differ[0]]), (4, 1));
    assert_eq!(ktx2.decode(&bytes, &Default::default()).unwrap().color.primaries, ColorPrimaries::Bt2020);
}

/// The bench's rows for BC6H (effort 0) and PFM on one input.
fn bench_rows(image: HdrImage) -> Vec<bench::Row> {
    let registry = hdrcodec::registry();
    let mut configs: Vec<Config> =
        bench::configurations(&registry).into_iter().filter(|c| c.label == "bc6h:effort0").collect();
    assert_eq!(configs.len(), 1, "the bench has a bc6h:effort0 row");
    let settings = EncodeSettings::default();
    configs.push(Config { label: "pfm".into(), codec: codec("pfm"), settings, ..configs[0].clone() });
    configs.push(Config { label: "bc6h-ktx2:effort0".into(), codec: codec("bc6h-ktx2"), ..configs[0].clone() });
    let inputs = [Input { name: "bt2020-ramps".into(), image }];
    let report = bench::run(&configs, &inputs, 1, &ThreadPool::single(), "test", Vec::new(), |_, _, _| {});
    for r in &report.rows {
        assert!(r.error.is_none(), "{}: {:?}", r.config, r.error);
    }
    report.rows
}

#[test]
fn bench_scores_bc6h_on_bt2020_like_on_bt709() {
    // Issue 9 measured BC6H on this scene at PU21-PSNR 25 dB and ΔE ITP 54 (the image was
    // converted to BT.709 and UF16 clamped the negative results; replayed below: 25.2 dB,
    // 54.4). Now the samples are kept and the decoded file, unspecified, is scored in the
    // reference's primaries.
    let img = bt2020_ramps();
    let rows = bench_rows(img.clone());
    let rows709 = bench_rows(labelled(&img, ColorPrimaries::Bt709));
    for (r, r709) in rows.iter().zip(&rows709) {
        eprintln!(
            "{:<18} BT.2020: PU21-PSNR {:.2} dB, ΔE ITP mean {:.4}; labelled BT.709: {:.2} dB, {:.4}; notes {:?}",
            r.config, r.pu21_psnr, r.de_itp_mean, r709.pu21_psnr, r709.de_itp_mean, r.notes
        );
        no_conversion(&r.notes, &r.config);
    }
    let row = |rows: &[bench::Row], label: &str| rows.iter().find(|r| r.config == label).unwrap().clone();
    let pfm = row(&rows, "pfm");
    assert!(pfm.identical && pfm.de_itp_mean == 0.0, "PFM keeps every sample: {pfm:?}");
    // BC6H at effort 0 on this scene, measured when this test was written: ΔE ITP mean 0.099,
    // PU21-PSNR 54.5 dB (labelled BT.709: 0.096, 54.6 dB); the bounds leave a margin for encoder
    // changes and stay far from the 54 and 25 dB of the issue.
    for label in ["bc6h:effort0", "bc6h-ktx2:effort0"] {
        let (r, r709) = (row(&rows, label), row(&rows709, label));
        assert!(r.de_itp_mean < 0.5, "{label}: ΔE ITP mean {}", r.de_itp_mean);
        assert!(r.pu21_psnr > 48.0, "{label}: PU21-PSNR {}", r.pu21_psnr);
        // Like the BT.709 label: the same file bytes, scored against the same samples; only
        // the metric's reading of the colours differs (BT.2020 colours are further apart).
        assert_eq!(r.bytes, r709.bytes, "{label}");
        assert!((r.pu21_psnr - r709.pu21_psnr).abs() < 3.0, "{label}: {} vs {} dB", r.pu21_psnr, r709.pu21_psnr);
        assert!(r.de_itp_mean < 2.0 * r709.de_itp_mean + 0.1, "{label}: {} vs {}", r.de_itp_mean, r709.de_itp_mean);
    }
}

#[test]
fn the_old_conversion_to_bt709_is_what_cost_bc6h_its_score() {
    // The path issue 9 measured, replayed: converted to BT.709 before encoding (UF16 then clamps
    // the negative components of colours outside BT.709), read back as BT.709.
    let img = bt2020_ramps();
    let bc6h = codec("bc6h");
    let settings = EncodeSettings::default().with_effort(0).with_option("primaries", "bt709");
    let (bytes, _) = hdrcodec::encode_for(bc6h.as_ref(), &img, &settings).unwrap();
    let mut old = bc6h.decode(&bytes, &Default::default()).unwrap();
    old.color.primaries = ColorPrimaries::Bt709;
    let c = hdrcodec::core::metrics::compare(&img, &old).unwrap();
    eprintln!(
        "bc6h:effort0 through BT.709 (the old path): PU21-PSNR {:.2} dB, ΔE ITP mean {:.2}",
        c.pu21_psnr, c.de_itp_mean
    );
    assert!(c.de_itp_mean > 10.0, "{c:?}");
}
