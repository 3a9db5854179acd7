//! Truncation and corruption sweeps over DDS and KTX2 files: every prefix and many corrupted
//! variants must give `Ok` or an `Error`, never a panic, and never a silently short image.
use hdrcodec_bc6h::texture::level_size;
use hdrcodec_bc6h::{surface_bytes, write_dds, write_ktx2, Bc6hDdsCodec, Bc6hKtx2Codec, Bc6hTexture};
use hdrcodec_core::{ColorPrimaries, Error, ImageCodec, Limits};

/// A 2-level 9x7 texture whose blocks are arbitrary bytes (every block decodes to something).
fn texture(signed: bool) -> Bc6hTexture {
    let levels = (0..2)
        .map(|i| {
            let (w, h) = level_size(9, 7, i);
            (0..surface_bytes(w, h).unwrap()).map(|b| (b * 131 + 17 * i) as u8).collect()
        })
        .collect();
    Bc6hTexture { width: 9, height: 7, signed, levels }
}

fn sweep(codec: &dyn ImageCodec, file: &[u8]) {
    let limits = Limits::fuzzing();
    let full = codec.decode(file, &limits).expect("the intact file decodes");
    assert_eq!((full.width(), full.height()), (9, 7));
    // Every truncation: the whole of level 0 must be present, so any cut is an error for DDS;
    // KTX2 stores level 0 last, so every cut is an error there too.
    for n in 0..file.len() {
        match codec.decode(&file[..n], &limits) {
            Err(Error::Truncated { .. } | Error::Invalid { .. } | Error::Unsupported { .. }) => {}
            Ok(_) => panic!("{}: a file cut to {n} of {} bytes decoded", codec.name(), file.len()),
            Err(e) => panic!("{}: unexpected error kind for a cut at {n}: {e}", codec.name()),
        }
    }
    // Corruption: each header byte set to a few values, plus bit flips everywhere.
    let header = file.len().min(200);
    let mut tried = 0;
    for i in 0..header {
        for v in [0u8, 1, 0x7F, 0x80, 0xFF, file[i] ^ 0x10] {
            let mut bad = file.to_vec();
            bad[i] = v;
            if let Ok(img) = codec.decode(&bad, &limits) {
                assert_eq!(img.samples().len(), img.width() as usize * img.height() as usize * 3);
            }
            tried += 1;
        }
    }
    for i in 0..file.len() * 8 {
        let mut bad = file.to_vec();
        bad[i / 8] ^= 1 << (i % 8);
        let _ = codec.decode(&bad, &limits);
        tried += 1;
    }
    assert!(tried > 1000);
}

#[test]
fn dds_truncation_and_corruption_sweep() {
    for signed in [false, true] {
        sweep(&Bc6hDdsCodec, &write_dds(&texture(signed)).unwrap());
    }
}

#[test]
fn ktx2_truncation_and_corruption_sweep() {
    for signed in [false, true] {
        sweep(&Bc6hKtx2Codec, &write_ktx2(&texture(signed), ColorPrimaries::Bt2020).unwrap());
    }
}

#[test]
fn huge_declared_sizes_are_refused_before_allocating() {
    let mut dds = write_dds(&texture(false)).unwrap();
    dds[12..16].copy_from_slice(&60000u32.to_le_bytes()); // height
    dds[16..20].copy_from_slice(&60000u32.to_le_bytes()); // width
    dds[28..32].copy_from_slice(&1u32.to_le_bytes());
    let e = Bc6hDdsCodec.decode(&dds, &Limits::fuzzing()).unwrap_err();
    assert!(matches!(e, Error::LimitExceeded { .. }), "{e}");
    // Within the limits but far more than the data: truncated, not an allocation.
    let e = Bc6hDdsCodec.decode(&dds, &Limits::none()).unwrap_err();
    assert!(matches!(e, Error::Truncated { .. }), "{e}");
}
