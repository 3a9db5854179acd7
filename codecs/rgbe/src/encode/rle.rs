//! The new-style RLE writer: rgbe.c's choice of runs and literals (`RGBE_WriteBytes_RLE`),
//! found with bit masks instead of a byte-by-byte scan.
//!
//! rgbe.c walks a channel from the current position in maximal runs of equal bytes (at most
//! 127 long) and stops at the first one of 4 or more bytes; the bytes before it are literals,
//! except that a single run of 2 or 3 bytes right at the current position is written as a run.
//! That first run of 4 or more starts at the first position `p` with `d[p] == d[p+1] ==
//! d[p+2] == d[p+3]`: were `p` inside an earlier walked run, that run would already hold
//! these four bytes and be 4 long. So the writer needs only one mask per channel, bit `i` set
//! when `d[i] == d[i+1]`: three shifted copies ANDed give the positions of four equal bytes
//! (the next one is a bit scan), and the run length at `p` is the count of set bits from `p`.

/// Spare bytes after each plane: literals are copied as fixed 128-byte blocks, and the mask
/// kernels read up to 64 bytes past the last 64-byte block start. What they read there is
/// masked off or overwritten.
pub(super) const PAD: usize = 128;

/// The longest literal (rgbe.c writes at most 128 bytes per literal code).
const MAX_LITERAL: usize = 128;
/// The longest run (a run code is 128 + length in one byte; rgbe.c stops at 127).
const MAX_RUN: usize = 127;

/// Words of the equality mask of an `n`-byte plane, plus a zero word so that a word's
/// successor can always be read.
pub(super) fn mask_words(n: usize) -> usize {
    n.div_ceil(64) + 1
}

/// The most bytes [`write_plane`] writes for an `n`-byte plane: `n + n/128 + 1`.
///
/// Each step of the writer covers an optional 2-3 byte run (2 bytes out), `L` literal bytes
/// (`L + ceil(L/128)` out) and a run of `R >= 4` bytes (2 out), so it writes at most
/// `ceil(L/128) - 2 < L/128` bytes more than it covers; the last step may end without a run,
/// adding at most `L/128 + 1`. Summed: at most `n + n/128 + 1`.
pub(super) fn plane_bound(n: usize) -> usize {
    n + n / 128 + 1
}

/// Appends the new-style RLE of one channel (`plane`: `n` bytes followed by [`PAD`] more)
/// to `out` at `o` and returns the new position; `out` must have room for
/// [`plane_bound`]`(n)` bytes from `o` plus [`PAD`] (literals are copied in fixed blocks).
/// `eq` ([`mask_words`]`(n)` words) is scratch space for the channel's equality mask.
/// AVX2 when [`hdrcodec_core::cpu::avx2`] allows it.
pub(super) fn write_channel(plane: &[u8], n: usize, eq: &mut [u64], out: &mut [u8], o: usize) -> usize {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, FMA and F16C (detected
        // once; `HDRCODEC_CPU` can only lower the level), which covers the `avx2` that
        // `write_channel_avx2` requires (its vector loads stay inside a checked 65-byte array).
        return unsafe { write_channel_avx2(plane, n, eq, out, o) };
    }
    eq_mask_portable(plane, n, eq);
    write_plane(plane, n, eq, out, o)
}

/// [`write_channel`] with the AVX2 mask kernel, and the writer built for AVX2 too (its fixed
/// 128-byte literal copies become four 32-byte moves).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn write_channel_avx2(plane: &[u8], n: usize, eq: &mut [u64], out: &mut [u8], o: usize) -> usize {
    // SAFETY: the CPU supports AVX2 (this function's own requirement).
    unsafe { eq_mask_avx2(plane, n, eq) };
    write_plane(plane, n, eq, out, o)
}

/// The bits of word `w` that stand for a real pair `(i, i + 1)` with `i + 1 < n`.
#[inline(always)]
fn valid_bits(w: usize, n: usize) -> u64 {
    let pairs = n.saturating_sub(1).saturating_sub(w * 64);
    if pairs >= 64 {
        u64::MAX
    } else {
        (1u64 << pairs) - 1
    }
}

/// The portable equality mask (and the twin the AVX2 kernel is tested against).
#[inline(always)]
fn eq_mask_portable(plane: &[u8], n: usize, eq: &mut [u64]) {
    for (w, word) in eq.iter_mut().enumerate() {
        let base = w * 64;
        *word = if base + 1 < n {
            let d: &[u8; 65] = plane[base..base + 65].try_into().expect("65 bytes");
            let mut bits = 0u64;
            for k in 0..64 {
                bits |= u64::from(d[k] == d[k + 1]) << k;
            }
            bits & valid_bits(w, n)
        } else {
            0
        };
    }
}

/// The AVX2 twin of [`eq_mask_portable`]: two byte compares of 32 lanes and their sign
/// masks per word.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn eq_mask_avx2(plane: &[u8], n: usize, eq: &mut [u64]) {
    use std::arch::x86_64::{__m256i, _mm256_cmpeq_epi8, _mm256_loadu_si256, _mm256_movemask_epi8};
    for (w, word) in eq.iter_mut().enumerate() {
        let base = w * 64;
        *word = if base + 1 < n {
            let d: &[u8; 65] = plane[base..base + 65].try_into().expect("65 bytes");
            let p = d.as_ptr();
            // SAFETY: `d` has 65 bytes; the 32-byte loads at offsets 0, 1, 32 and 33 end at
            // byte 65 at the latest.
            let (lo, hi) = unsafe {
                let at = |k: usize| _mm256_loadu_si256(p.add(k).cast::<__m256i>());
                (_mm256_cmpeq_epi8(at(0), at(1)), _mm256_cmpeq_epi8(at(32), at(33)))
            };
            let bits = u64::from(_mm256_movemask_epi8(lo) as u32) | u64::from(_mm256_movemask_epi8(hi) as u32) << 32;
            bits & valid_bits(w, n)
        } else {
            0
        };
    }
}

/// The positions where a maximal run of 4 or more equal bytes starts, as the bits of word
/// `w`: four equal bytes start there (the pairs (i, i+1), (i+1, i+2), (i+2, i+3) are equal)
/// and the byte before differs (or there is none).
#[inline(always)]
fn run_starts(eq: &[u64], w: usize) -> u64 {
    let (a, b) = (eq[w], eq[w + 1]);
    let before = if w > 0 { eq[w - 1] >> 63 } else { 0 };
    a & (a >> 1 | b << 63) & (a >> 2 | b << 62) & !(a << 1 | before)
}

/// The length of the maximal run of equal bytes starting at `p`.
#[inline(always)]
fn run_length(eq: &[u64], p: usize) -> usize {
    let mut len = 1;
    let mut i = p;
    loop {
        let shift = i % 64;
        // The shift brings in zeros from the top, so the count stops at the word's end.
        let ones = (!(eq[i / 64] >> shift)).trailing_zeros() as usize;
        len += ones;
        i += ones;
        if ones < 64 - shift {
            return len;
        }
    }
}

/// Writes the bytes `cur..p` that come before a run (or the end): rgbe.c writes 2 or 3 equal
/// bytes as a run, anything else as literals of at most 128 bytes.
///
/// The random mix of short literals and short runs makes branches on their lengths
/// mispredict, so the common case (a literal of at most 128 bytes or a short run) is written
/// without them: a short run `[128 + len, v]` and a literal `[len, v, ...]` differ only in
/// the code byte and in how far the output moves.
#[inline(always)]
fn write_gap(plane: &[u8], mut cur: usize, p: usize, out: &mut [u8], mut o: usize) -> usize {
    let mut gap = p - cur;
    let (a, b, c) = (plane[cur], plane[cur + 1], plane[cur + 2]);
    let short = (gap == 2 && a == b) | (gap == 3 && a == b && b == c);
    // Longer literals start with whole 128-byte ones.
    while gap > MAX_LITERAL {
        out[o] = MAX_LITERAL as u8;
        out[o + 1..o + 1 + MAX_LITERAL].copy_from_slice(&plane[cur..cur + MAX_LITERAL]);
        o += 1 + MAX_LITERAL;
        cur += MAX_LITERAL;
        gap -= MAX_LITERAL;
    }
    // The rest: nothing (gap 0: the code byte and the copy are overwritten next or lie past
    // the end), a short run or one literal. A fixed-size copy (vector moves, no memcpy
    // call); what lies past the literal is overwritten next or lies past the end.
    out[o] = gap as u8 + if short { 128 } else { 0 };
    out[o + 1..o + 1 + MAX_LITERAL].copy_from_slice(&plane[cur..cur + MAX_LITERAL]);
    o + if short {
        2
    } else if gap > 0 {
        1 + gap
    } else {
        0
    }
}

/// [`write_channel`] once the equality mask `eq` is made.
///
/// rgbe.c's scan for the next run of 4 or more from the current position always lands on the
/// start of the next maximal run of 4 or more equal bytes (the current position is never
/// inside one: runs longer than 127 are written as 127-byte runs until fewer than 4 bytes
/// are left, which then belong to the next gap). So the writer walks the run starts, bits of
/// a mask computed from the data alone, instead of scanning on from each position: no chain
/// of loads from one operation to the next.
#[inline(always)]
fn write_plane(plane: &[u8], n: usize, eq: &[u64], out: &mut [u8], mut o: usize) -> usize {
    let mut cur = 0;
    for w in 0..eq.len() - 1 {
        let mut starts = run_starts(eq, w);
        while starts != 0 {
            let p = w * 64 + starts.trailing_zeros() as usize;
            starts &= starts - 1;
            o = write_gap(plane, cur, p, out, o);
            let len = run_length(eq, p);
            let mut left = len;
            while left >= 4 {
                let run = left.min(MAX_RUN);
                out[o] = 128 + run as u8;
                out[o + 1] = plane[p];
                o += 2;
                left -= run;
            }
            cur = p + len - left;
        }
    }
    if cur < n {
        o = write_gap(plane, cur, n, out, o);
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use hdrcodec_core::cpu::{self, CpuLevel};

    /// The encoder's previous, byte-at-a-time writer: the same choice of runs and literals as
    /// rgbe.c's `RGBE_WriteBytes_RLE`, which `truncating_writer_is_byte_identical_to_oiio`
    /// confirmed on the corpus. The mask writer is checked against this simple form.
    fn reference(data: &[u8], out: &mut Vec<u8>) {
        const MIN_RUN: usize = 4;
        let n = data.len();
        let mut cur = 0;
        while cur < n {
            let mut beg = cur;
            let mut run = 0;
            let mut old_run = 0;
            while run < MIN_RUN && beg < n {
                beg += run;
                old_run = run;
                run = 1;
                if beg < n {
                    let v = data[beg];
                    run += data[beg + 1..n.min(beg + 127)].iter().take_while(|&&b| b == v).count();
                }
            }
            if old_run > 1 && old_run == beg - cur {
                out.push(128 + old_run as u8);
                out.push(data[cur]);
                cur = beg;
            }
            while cur < beg {
                let k = (beg - cur).min(128);
                out.push(k as u8);
                out.extend_from_slice(&data[cur..cur + k]);
                cur += k;
            }
            if run >= MIN_RUN {
                out.push(128 + run as u8);
                out.push(data[beg]);
                cur += run;
            }
        }
    }

    fn write(data: &[u8], avx2: bool) -> Vec<u8> {
        let n = data.len();
        let mut plane = data.to_vec();
        // Padding equal to the last byte: the masks must ignore it.
        plane.extend(std::iter::repeat_n(data.last().copied().unwrap_or(0), PAD));
        let mut eq = vec![0u64; mask_words(n)];
        let mut out = vec![0xEE; 3 + plane_bound(n) + PAD];
        let end = if avx2 {
            write_channel(&plane, n, &mut eq, &mut out, 3)
        } else {
            eq_mask_portable(&plane, n, &mut eq);
            write_plane(&plane, n, &eq, &mut out, 3)
        };
        assert!(end - 3 <= plane_bound(n), "n = {n}: {} bytes", end - 3);
        out[3..end].to_vec()
    }

    #[test]
    fn rle_runs_and_literals() {
        // The encoding rules of the Radiance format (Ward, "Real Pixels", Graphics Gems II, and
        // the Radiance file-format notes): a count byte > 128 is a run of (count - 128) copies of
        // the next byte, a count of 1-128 is followed by that many literal bytes.
        assert_eq!(write(&[7; 10], false), [138, 7]);
        assert_eq!(write(&[1, 2, 3], false), [3, 1, 2, 3]);
        assert_eq!(write(&[5, 5, 9, 9, 9, 9, 9], false), [130, 5, 133, 9]);
        // 300 equal bytes: runs of 127, 127 and 46.
        assert_eq!(write(&[4; 300], false), [255, 4, 255, 4, 128 + 46, 4]);
    }

    /// Random channels built from runs of every length and literal stretches, against the
    /// reference loop; the portable writer and the one `write_channel` picks (AVX2 where the
    /// CPU has it, unless `HDRCODEC_CPU=scalar`).
    #[test]
    fn mask_writer_matches_rgbe_c() {
        let mut next = crate::test_rng(0x2545_F491_4F6C_DD1Du64);
        let mut cases: Vec<Vec<u8>> = Vec::new();
        for n in (1..300).chain([511, 512, 513, 1000, 1024, 4097]) {
            for style in 0..4 {
                let mut d = Vec::with_capacity(n);
                while d.len() < n {
                    let r = next();
                    let len = match style {
                        0 => (r % 6) as usize + 1,
                        1 => [1, 2, 3, 4, 5, 63, 64, 65, 126, 127, 128, 129, 200][(r % 13) as usize],
                        2 => 1,
                        _ => (r % 300) as usize + 1,
                    };
                    // Few distinct values so that neighbouring runs often repeat a value.
                    let v = if style == 2 { (r >> 8) as u8 } else { (r >> 8) as u8 % 3 };
                    d.extend(std::iter::repeat_n(v, len));
                }
                d.truncate(n);
                cases.push(d);
            }
        }
        // Worst cases for the size bound: alternating bytes, and a 4-run after every literal.
        cases.push((0..1000).map(|i| (i % 2) as u8).collect());
        cases.push((0..1000).map(|i| if i % 133 < 129 { (i % 2) as u8 } else { 9 }).collect());
        for d in &cases {
            let mut want = Vec::new();
            reference(d, &mut want);
            assert_eq!(write(d, false), want, "{d:?}");
            assert_eq!(write(d, true), want, "{d:?}");
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_mask_matches_the_portable_twin() {
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "avx2_mask_matches_the_portable_twin") {
            return;
        }
        let mut next = crate::test_rng(0x9E37_79B9_7F4A_7C15u64);
        for n in (0..200).chain([1023, 1024, 1025]) {
            let plane: Vec<u8> = (0..n + PAD).map(|_| (next() % 3) as u8).collect();
            let (mut a, mut b) = (vec![1u64; mask_words(n)], vec![2u64; mask_words(n)]);
            eq_mask_portable(&plane, n, &mut a);
            // SAFETY: `twin_test_can_run` above found AVX2 (with FMA and F16C) in the hardware.
            unsafe { eq_mask_avx2(&plane, n, &mut b) };
            assert_eq!(a, b, "n = {n}");
            // And the portable mask is its definition.
            for i in 0..a.len() * 64 {
                let want = i + 1 < n && plane[i] == plane[i + 1];
                assert_eq!(a[i / 64] >> (i % 64) & 1 == 1, want, "n = {n}, bit {i}");
            }
        }
    }
}
