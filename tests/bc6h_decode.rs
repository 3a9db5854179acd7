//! BC6H decoder validation: a differential test against `bcdec_rs` over random blocks, and
//! (below) the corpus DDS files against imagecodecs (bcdec 0.98) and the EXR they came from.
mod common;

use hdrcodec_bc6h::decode_block;

/// xorshift64* : deterministic, fast, good enough to spread bits over whole blocks.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn block(&mut self) -> [u8; 16] {
        let mut b = [0u8; 16];
        b[..8].copy_from_slice(&self.next().to_le_bytes());
        b[8..].copy_from_slice(&self.next().to_le_bytes());
        b
    }
}

fn bcdec(block: &[u8; 16], signed: bool) -> [u16; 48] {
    let mut out = [0u16; 48];
    bcdec_rs::bc6h_half(block, &mut out, 12, signed);
    out
}

/// Random blocks per variant. The low 5 bits cycle through all 32 values so every mode (and
/// every reserved value) gets 1/32 of the blocks; the other 123 bits are random.
const RANDOM_BLOCKS: u64 = 10_000_000;

fn differential(signed: bool, seed: u64) {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    let per = RANDOM_BLOCKS.div_ceil(threads);
    let start = std::time::Instant::now();
    let checked: u64 = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || {
                    let mut rng = Rng(seed ^ (t + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
                    let mut n = 0u64;
                    for i in 0..per.min(RANDOM_BLOCKS.saturating_sub(t * per)) {
                        let mut block = rng.block();
                        block[0] = (block[0] & !31) | (i % 32) as u8;
                        let ours = decode_block(&block, signed);
                        let theirs = bcdec(&block, signed);
                        assert_eq!(
                            ours.as_flattened(),
                            &theirs[..],
                            "block {block:02x?} (signed={signed}) differs from bcdec_rs"
                        );
                        n += 1;
                    }
                    n
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).sum()
    });
    assert_eq!(checked, RANDOM_BLOCKS);
    println!(
        "bc6h differential ({}): {checked} random blocks bit-identical to bcdec_rs in {:.2} s",
        if signed { "SF16" } else { "UF16" },
        start.elapsed().as_secs_f64()
    );
}

#[test]
fn random_blocks_match_bcdec_rs_uf16() {
    differential(false, 0x5EED_0001);
}

#[test]
fn random_blocks_match_bcdec_rs_sf16() {
    differential(true, 0x5EED_0002);
}
