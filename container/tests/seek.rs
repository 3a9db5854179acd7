//! SeekReader: single tiles through END → INDX → DATA, checked against the in-memory Reader.

use hdrcodec_container::{encode_frames, RawF16Codec, Reader, SeekReader};
use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, Limits};
use std::io::Cursor;

fn sample_file() -> Vec<u8> {
    let frames: Vec<HdrImage> = (0..3)
        .map(|f| {
            let s = (0..70 * 33 * 3).map(|i| (i * 3 + f * 1000) as f32 * 0.01).collect();
            HdrImage::new(70, 33, Channels::Rgb, s, ColorInfo::default()).unwrap()
        })
        .collect();
    encode_frames(&frames, &RawF16Codec, &EncodeSettings::default(), Some(32)).unwrap()
}

/// Every (frame, column, row) of the file's grid.
fn grid(r: &Reader<'_>) -> Vec<(u32, u32, u32)> {
    let h = *r.head();
    (0..h.frames)
        .flat_map(|f| (0..h.tile_rows()).flat_map(move |y| (0..h.tile_columns()).map(move |x| (f, x, y))))
        .collect()
}

#[test]
fn every_tile_matches_the_in_memory_reader() {
    let file = sample_file();
    let r = Reader::new(&file, &Limits::default()).unwrap();
    let mut s = SeekReader::new(Cursor::new(&file), &Limits::default()).unwrap();
    assert_eq!(s.head(), r.head());
    assert_eq!(s.index().len(), 18);
    for (f, x, y) in grid(&r) {
        let want = r.tile(f, x, y).unwrap();
        let (header, payload) = s.read_tile(f, x, y).unwrap();
        assert_eq!((header, payload.as_slice()), (want.header, want.payload));
    }
    assert!(s.read_tile(3, 0, 0).is_err() && s.read_tile(0, 3, 0).is_err());

    // The same through a file on disk.
    let path = std::env::temp_dir().join(format!("hdrcodec-container-seek-{}.hdrc", std::process::id()));
    std::fs::write(&path, &file).unwrap();
    let mut s = SeekReader::new(std::fs::File::open(&path).unwrap(), &Limits::default()).unwrap();
    let (h, p) = s.read_tile(2, 2, 1).unwrap();
    assert_eq!((h, p.as_slice()), (r.tile(2, 2, 1).unwrap().header, r.tile(2, 2, 1).unwrap().payload));
    std::fs::remove_file(&path).unwrap();
}

/// Opens `data` and reads every tile; anything that succeeds must equal the original file's.
fn read_all(data: &[u8], reference: &Reader<'_>) -> usize {
    let Ok(mut s) = SeekReader::new(Cursor::new(data), &Limits::fuzzing()) else { return 0 };
    let mut ok = 0;
    for (f, x, y) in grid(reference) {
        if let Ok((header, payload)) = s.read_tile(f, x, y) {
            let want = reference.tile(f, x, y).unwrap();
            assert_eq!((header, payload.as_slice()), (want.header, want.payload), "tile ({x}, {y}) of frame {f}");
            ok += 1;
        }
    }
    ok
}

#[test]
fn damage_never_yields_a_wrong_tile() {
    let file = sample_file();
    let reference = Reader::new(&file, &Limits::default()).unwrap();
    for n in 0..file.len() {
        assert_eq!(read_all(&file[..n], &reference), 0, "truncated to {n} bytes: the END chunk is gone");
    }
    let first_data = reference.data_chunks()[0].offset as usize;
    for i in (0..file.len()).step_by(3) {
        for x in [0x01u8, 0x80] {
            let mut bad = file.clone();
            bad[i] ^= x;
            let ok = read_all(&bad, &reference);
            // A damaged byte inside a tile's chunk costs exactly that tile; elsewhere before the
            // tiles (signature, HEAD) or in INDX / END, the file does not open.
            if let Some(d) = reference.data_chunks().iter().find(|d| {
                let o = d.offset as usize;
                (o..o + 12 + 20 + d.payload.len()).contains(&i)
            }) {
                assert_eq!(ok, 17, "byte {i} ^ {x:#x} in the DATA chunk at {}", d.offset);
            } else if i < first_data {
                // COLR lies here too, and SeekReader does not read it.
                assert!(ok == 0 || ok == 18, "byte {i} ^ {x:#x}: {ok} tiles");
            } else {
                assert_eq!(ok, 0, "byte {i} ^ {x:#x} in INDX or END");
            }
        }
    }
}
