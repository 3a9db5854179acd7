//! The run-length coding of TIFF Compression 34676 (SGILOG). Each row is coded separately, one
//! byte plane after the other, most significant byte first (4 planes for LogLuv32, 2 for LogL16).
//! Within a plane, a control byte `n < 128` is followed by `n` literal bytes and a control byte
//! `n ≥ 128` repeats the next byte `n - 126` times (2..=129).

use hdrcodec_core::{Error, Result};

/// Longest run one control byte can code.
const MAX_RUN: usize = 129;
/// Longest literal block one control byte can code.
const MAX_LITERAL: usize = 127;
/// Shortest repeat worth a run: a run of 3 takes 2 bytes instead of 3 literal bytes.
const MIN_RUN: usize = 3;

/// Decodes one row of `out.len()` pixels of `planes` byte planes from `src[*pos..]`, advancing
/// `*pos`. A run or literal that goes past the row's end is an error (the reference decoder
/// silently drops the excess; its encoder never writes it).
pub(crate) fn decode_row(src: &[u8], pos: &mut usize, out: &mut [u32], planes: u32, row: u32) -> Result<()> {
    out.fill(0);
    let n = out.len();
    let mut p = *pos;
    for plane in (0..planes).rev() {
        let shift = plane * 8;
        let mut i = 0;
        while i < n {
            let Some(&ctl) = src.get(p) else {
                return Err(Error::truncated(format!("the SGILOG data of row {row} ({} of {n} pixels)", i)));
            };
            p += 1;
            if ctl >= 128 {
                let len = usize::from(ctl) - 126;
                let Some(&b) = src.get(p) else {
                    return Err(Error::truncated(format!("a run in the SGILOG data of row {row}")));
                };
                p += 1;
                if len > n - i {
                    return Err(Error::invalid(format!("an SGILOG run of {len} overflows row {row} at pixel {i}")));
                }
                let v = u32::from(b) << shift;
                out[i..i + len].iter_mut().for_each(|w| *w |= v);
                i += len;
            } else {
                let len = usize::from(ctl);
                if len > n - i {
                    return Err(Error::invalid(format!(
                        "an SGILOG literal of {len} bytes overflows row {row} at pixel {i}"
                    )));
                }
                let Some(bytes) = src.get(p..p + len) else {
                    return Err(Error::truncated(format!("a literal in the SGILOG data of row {row}")));
                };
                p += len;
                for (w, &b) in out[i..i + len].iter_mut().zip(bytes) {
                    *w |= u32::from(b) << shift;
                }
                i += len;
            }
        }
    }
    *pos = p;
    Ok(())
}

/// Appends the coding of one row (`planes` byte planes of `words`) to `out`.
pub(crate) fn encode_row(words: &[u32], planes: u32, out: &mut Vec<u8>) {
    let mut plane_bytes = Vec::with_capacity(words.len());
    for plane in (0..planes).rev() {
        plane_bytes.clear();
        plane_bytes.extend(words.iter().map(|w| (w >> (plane * 8)) as u8));
        encode_plane(&plane_bytes, out);
    }
}

/// Greedy coding of one byte plane: runs of at least [`MIN_RUN`] equal bytes become runs, the
/// rest literal blocks.
fn encode_plane(b: &[u8], out: &mut Vec<u8>) {
    let n = b.len();
    let mut i = 0;
    let mut lit_start = 0;
    while i < n {
        let mut run = 1;
        while run < MAX_RUN && i + run < n && b[i + run] == b[i] {
            run += 1;
        }
        if run >= MIN_RUN {
            flush_literals(&b[lit_start..i], out);
            out.push((run + 126) as u8);
            out.push(b[i]);
            i += run;
            lit_start = i;
        } else {
            i += run;
        }
    }
    flush_literals(&b[lit_start..n], out);
}

fn flush_literals(lit: &[u8], out: &mut Vec<u8>) {
    for chunk in lit.chunks(MAX_LITERAL) {
        out.push(chunk.len() as u8);
        out.extend_from_slice(chunk);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_of_runs_and_literals() {
        let mut words: Vec<u32> =
            (0..700u32).map(|i| if i % 97 < 40 { 0x1234_5678 } else { i.wrapping_mul(2654435761) }).collect();
        words.extend(std::iter::repeat_n(7, 300));
        for planes in [2, 4] {
            let mask = if planes == 2 { 0xffff } else { u32::MAX };
            let mut enc = Vec::new();
            encode_row(&words, planes, &mut enc);
            let mut back = vec![0; words.len()];
            let mut pos = 0;
            decode_row(&enc, &mut pos, &mut back, planes, 0).unwrap();
            assert_eq!(pos, enc.len());
            assert!(back.iter().zip(&words).all(|(a, b)| *a == b & mask));
        }
    }

    #[test]
    fn overflow_and_truncation_are_errors() {
        let mut out = [0u32; 4];
        // A run of 5 in a 4-pixel row.
        assert!(decode_row(&[128 + 3, 1], &mut 0, &mut out, 2, 0).is_err());
        // A literal of 3 where only 2 bytes follow.
        assert!(decode_row(&[3, 1, 2], &mut 0, &mut out, 2, 0).is_err());
        // The second plane is missing.
        assert!(decode_row(&[128 + 2, 9], &mut 0, &mut out, 2, 0).is_err());
        // A zero-length literal is a no-op; then one run fills each plane.
        let mut pos = 0;
        decode_row(&[0, 128 + 2, 9, 128 + 2, 1], &mut pos, &mut out, 2, 0).unwrap();
        assert_eq!(out, [0x901; 4]);
    }
}
