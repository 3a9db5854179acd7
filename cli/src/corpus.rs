//! The project's own generated corpus: a few small synthetic HDR scenes, each built to stress
//! one thing a codec can get wrong (extreme peaks, wide-gamut colour, near-black noise, sharp
//! edges, specular highlights, odd sizes, alpha).
//!
//! Generation is deterministic: every scene draws from its own seeded [`SplitMix64`], so the
//! same build gives the same samples on every call (tests hash them). `corpus/README.md`
//! describes each scene and `corpus/MANIFEST.tsv` lists what [`manifest`] writes for them.
//!
//! All scenes use `nits_per_unit = 100` (a sample value of 1.0 is 100 cd/m²).
//!
//! ```
//! let scenes = hdrcodec_cli::corpus::scenes();
//! assert!(scenes.iter().any(|s| s.name == "sun-sky"));
//! ```

use hdrcodec::core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, Error, HdrImage, Result};
use hdrcodec::{luminance, Registry};
use std::path::{Path, PathBuf};

/// Absolute luminance of a sample value 1.0 in every generated scene, cd/m².
pub const NITS_PER_UNIT: f32 = 100.0;

/// A small, fast, well-mixed PRNG: SplitMix64 (Steele, Lea & Flood, "Fast splittable
/// pseudorandom number generators", OOPSLA 2014). Our own so the corpus never changes with a
/// dependency's version.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.0)
    }

    /// Uniform in [0, 1) with 53 bits of precision.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A standard normal deviate (Box-Muller; one of the pair is discarded for simplicity).
    pub fn gaussian(&mut self) -> f64 {
        // 1 - u keeps the argument of ln in (0, 1].
        let u1 = 1.0 - self.next_f64();
        let u2 = self.next_f64();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// The SplitMix64 output function: a bijective 64-bit mixer.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// One generated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Short stable name, also the file stem written by [`write`].
    pub name: &'static str,
    /// What the scene stresses (one line).
    pub description: &'static str,
    /// The pixels.
    pub image: HdrImage,
}

type Generator = fn() -> HdrImage;

/// Every scene: (name, description, generator). Adding a scene is one line here.
const SCENES: &[(&str, &str, Generator)] = &[
    ("sun-sky", "sun disk peaking at ~1.5e5 nits over a 800-2200 nit sky gradient and dark ground", sun_sky),
    ("bt2020-ramps", "pure BT.2020 primaries and secondaries, log and linear ramps 0.1-1e4 nits", bt2020_ramps),
    ("dark-noise", "lognormal noise with mean 1e-3 nits (left half) beside a 50-200 nit gradient", dark_noise),
    ("edges", "checkerboard 0.01 / 1e4 nits (1e6:1), one-pixel lines, coloured hard edges", edges),
    ("specular", "value-noise texture at 30-150 nits with 40 sharp specular highlights of 5e3-4.5e4 nits", specular),
    ("tiny-1x1", "a single orange pixel: R 6000 nits, luminance about 3500 nits", tiny_1x1),
    ("odd-3x5", "3x5 pixels of log-uniform random values over 0.01-1e5 nits", odd_3x5),
    ("odd-257x129", "257x129 (no block size divides it) radial gradient 1-1e4 nits with noise", odd_257x129),
    ("alpha", "RGBA: hue sweep 10-2000 nits under a soft circular alpha with 0, 0.5 and 1 regions", alpha),
];

/// Names of all scenes, in corpus order.
pub fn scene_names() -> Vec<&'static str> {
    SCENES.iter().map(|s| s.0).collect()
}

/// Generates one scene by name.
pub fn scene(name: &str) -> Option<Scene> {
    SCENES.iter().find(|s| s.0 == name).map(|&(name, description, gen)| Scene { name, description, image: gen() })
}

/// Generates every scene (in parallel; each scene is deterministic on its own).
pub fn scenes() -> Vec<Scene> {
    use rayon::prelude::*;
    SCENES.par_iter().map(|&(name, description, gen)| Scene { name, description, image: gen() }).collect()
}

/// A large photograph-like image for memory and speed measurements (not part of the scene set):
/// a sky gradient over a darker ground, soft light sources of a few thousand nits, film-grain
/// noise, every sample rounded to half precision (as a camera-raw or EXR-half source would be).
/// Rows are generated in parallel from per-row seeds, so the result does not depend on threads.
pub fn large_photo(width: u32, height: u32) -> HdrImage {
    use rayon::prelude::*;
    let (w, h) = (width as usize, height as usize);
    let lights: Vec<(f64, f64, f64, f64)> = {
        let mut rng = SplitMix64::new(0x1a_29e5);
        (0..24)
            .map(|_| (rng.next_f64(), rng.next_f64(), 0.002 + 0.02 * rng.next_f64(), 5.0 + 60.0 * rng.next_f64()))
            .collect()
    };
    let mut samples = vec![0f32; w * h * 3];
    samples.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        let mut rng = SplitMix64::new(mix64(0x7a11_0000 ^ y as u64));
        let v = y as f64 / h.max(1) as f64;
        for (x, px) in row.chunks_exact_mut(3).enumerate() {
            let u = x as f64 / w.max(1) as f64;
            let base = if v < 0.55 {
                let t = v / 0.55;
                [2.0 + 6.0 * (1.0 - t), 3.0 + 7.0 * (1.0 - t), 6.0 + 9.0 * (1.0 - t)]
            } else {
                let t = (v - 0.55) / 0.45;
                let g = 0.05 + 0.4 * (1.0 - t) * (0.6 + 0.4 * (u * 7.0).sin().abs());
                [g * 1.1, g, g * 0.8]
            };
            let mut glow = 0.0;
            for &(lx, ly, r, peak) in &lights {
                let d2 = ((u - lx).powi(2) + (v - ly).powi(2)) / (r * r);
                if d2 < 40.0 {
                    glow += peak * (-d2).exp();
                }
            }
            let grain = 1.0 + 0.04 * rng.gaussian();
            for c in 0..3 {
                let value = ((base[c] + glow * [1.0, 0.85, 0.6][c]) * grain).max(0.0) as f32;
                px[c] = half::f16::from_f32(value).to_f32();
            }
        }
    });
    let color = ColorInfo { nits_per_unit: NITS_PER_UNIT, ..ColorInfo::default() };
    HdrImage::new(width, height, Channels::Rgb, samples, color).expect("the buffer matches the size")
}

/// FNV-1a (64-bit) over the bit patterns of all samples, then width, height and channels:
/// a fingerprint that changes if any sample changes by one ulp.
pub fn sample_hash(image: &HdrImage) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for s in image.samples() {
        eat(&s.to_bits().to_le_bytes());
    }
    eat(&image.width().to_le_bytes());
    eat(&image.height().to_le_bytes());
    eat(&(image.channels().count() as u32).to_le_bytes());
    h
}

/// The manifest of `scenes` as TSV: a header line, then one line per scene with name, file,
/// width, height, channels, primaries, peak and mean luminance (nits), sample hash, description.
pub fn manifest(scenes: &[Scene]) -> String {
    let mut out = String::from(
        "name\tfile\twidth\theight\tchannels\tprimaries\tpeak_nits\tmean_nits\tsample_fnv1a64\tdescription\n",
    );
    for s in scenes {
        let img = &s.image;
        let lum = luminance(img);
        let peak = lum.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mean = lum.iter().sum::<f64>() / lum.len() as f64;
        out.push_str(&format!(
            "{}\t{}.exr\t{}\t{}\t{}\t{}\t{:.4e}\t{:.4e}\t{:016x}\t{}\n",
            s.name,
            s.name,
            img.width(),
            img.height(),
            img.channels().count(),
            img.color.primaries.name(),
            peak,
            mean,
            sample_hash(img),
            s.description
        ));
    }
    out
}

/// Writes every scene as a lossless 32-bit float OpenEXR file (`DIR/<name>.exr`) plus
/// `DIR/MANIFEST.tsv`, each through a temporary file and a rename. Returns the paths written.
pub fn write(dir: &Path, registry: &Registry, mut progress: impl FnMut(&str)) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::invalid(format!("cannot create {}: {e}", dir.display())))?;
    let exr = registry.by_name("exr")?;
    let settings = EncodeSettings::default().with_option("pixel", "float").with_option("compression", "zip");
    let scenes = scenes();
    let mut written = Vec::new();
    for s in &scenes {
        progress(s.name);
        let path = dir.join(format!("{}.exr", s.name));
        let bytes = exr.encode(&s.image, &settings)?;
        hdrcodec::write_atomic(&path, &bytes)?;
        written.push(path);
    }
    let path = dir.join("MANIFEST.tsv");
    hdrcodec::write_atomic(&path, manifest(&scenes).as_bytes())?;
    written.push(path);
    Ok(written)
}

// ---------------------------------------------------------------------------------------------
// Scene generators. Values are in units of NITS_PER_UNIT (1.0 = 100 nits).

fn info(primaries: ColorPrimaries) -> ColorInfo {
    ColorInfo { primaries, nits_per_unit: NITS_PER_UNIT, hdr10: None }
}

/// Builds an image by calling `f(x, y)` for every pixel, rows top to bottom.
fn build<const N: usize>(
    w: u32,
    h: u32,
    primaries: ColorPrimaries,
    mut f: impl FnMut(u32, u32) -> [f32; N],
) -> HdrImage {
    let channels = Channels::from_count(N).expect("3 or 4 channels");
    let mut samples = Vec::with_capacity(w as usize * h as usize * N);
    for y in 0..h {
        for x in 0..w {
            samples.extend_from_slice(&f(x, y));
        }
    }
    HdrImage::new(w, h, channels, samples, info(primaries)).expect("generator sizes are consistent")
}

fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t]
}

fn scale3(a: [f32; 3], k: f32) -> [f32; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// Sun centre, radius (pixels) and the intensity of its centre (units) in `sun_sky`.
const SUN: (f32, f32, f32) = (380.0, 60.0, 1500.0);

fn sun_sky() -> HdrImage {
    let (w, h) = (512, 256);
    let horizon = 200;
    let mut rng = SplitMix64::new(0x5u64 << 32 | 1);
    let zenith_rgb = [4.0, 8.0, 20.0];
    let horizon_rgb = [20.0, 22.0, 25.0];
    let sun_rgb = [1.0, 0.98, 0.92];
    let (cx, cy, radius) = (SUN.0, SUN.1, SUN.1 / 6.0);
    build(w, h, ColorPrimaries::Bt709, |x, y| {
        if y >= horizon {
            // Ground: dark, textured, 20-80 nits.
            let g = 0.2 + 0.6 * rng.next_f64() as f32;
            return [g * 0.9, g * 0.7, g * 0.5];
        }
        let t = y as f32 / horizon as f32;
        let mut c = lerp3(zenith_rgb, horizon_rgb, t);
        // Glow around the sun, then the disk itself with 4x4 supersampled coverage and limb
        // darkening I(r) = I0 (1 - 0.6 (1 - sqrt(1 - (r/R)^2))).
        let d = ((x as f32 + 0.5 - cx).powi(2) + (y as f32 + 0.5 - cy).powi(2)).sqrt();
        c = add3(c, scale3(sun_rgb, 60.0 * (-d / 12.0).exp()));
        if d < radius + 2.0 {
            let mut acc = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = x as f32 + (sx as f32 + 0.5) / 4.0 - cx;
                    let py = y as f32 + (sy as f32 + 0.5) / 4.0 - cy;
                    let r = (px * px + py * py).sqrt() / radius;
                    if r < 1.0 {
                        acc += 1.0 - 0.6 * (1.0 - (1.0 - r * r).sqrt());
                    }
                }
            }
            c = add3(c, scale3(sun_rgb, SUN.2 * acc / 16.0));
        }
        c
    })
}

/// The six pure colours of `bt2020_ramps`, one band each.
const PURE: [[f32; 3]; 6] =
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 0.0]];

fn bt2020_ramps() -> HdrImage {
    let (w, h) = (384u32, 192u32);
    let band = h / PURE.len() as u32;
    build(w, h, ColorPrimaries::Bt2020, |x, y| {
        let colour = PURE[(y / band) as usize];
        let t = x as f32 / (w - 1) as f32;
        // Upper half of a band: logarithmic ramp 1e-3..1e2 units (0.1-1e4 nits);
        // lower half: linear ramp 0..50 units, where banding in dark steps shows.
        let v = if y % band < band / 2 { 10f32.powf(-3.0 + 5.0 * t) } else { 50.0 * t };
        scale3(colour, v)
    })
}

/// Mean luminance of the noisy left half of `dark_noise`, in units.
const DARK_MEAN: f64 = 1e-5;

fn dark_noise() -> HdrImage {
    let (w, h) = (256u32, 256u32);
    let mut rng = SplitMix64::new(0xDA4C);
    let sigma = 0.5;
    build(w, h, ColorPrimaries::Bt709, |x, y| {
        if x < w / 2 {
            // Lognormal with E[v] = DARK_MEAN: exp(σg - σ²/2) has mean 1. One shared factor keeps
            // luminance noise; a smaller per-channel factor adds chroma noise of mean 1.
            let common = (sigma * rng.gaussian() - sigma * sigma / 2.0).exp();
            let mut c = [0.0f32; 3];
            for v in &mut c {
                let s = 0.2;
                *v = (DARK_MEAN * common * (s * rng.gaussian() - s * s / 2.0).exp()) as f32;
            }
            c
        } else {
            let v = 0.5 + 1.5 * y as f32 / (h - 1) as f32;
            [v, v, v]
        }
    })
}

/// Dark and bright levels of the `edges` checkerboard (units): 0.01 and 1e4 nits.
const EDGE_LEVELS: (f32, f32) = (1e-4, 100.0);

fn edges() -> HdrImage {
    let (w, h) = (256u32, 256u32);
    let (lo, hi) = EDGE_LEVELS;
    build(w, h, ColorPrimaries::Bt709, |x, y| {
        if y < 160 {
            let v = if ((x / 16) + (y / 16)) % 2 == 0 { hi } else { lo };
            [v, v, v]
        } else if y < 208 {
            // One-pixel lines at the Nyquist frequency, then every third pixel.
            let on = if x < 128 { x % 2 == 0 } else { x % 3 == 0 };
            let v = if on { hi } else { lo };
            [v, v, v]
        } else {
            // Hard colour edges: saturated red | cyan | blue | yellow, 8 px wide steps.
            const C: [[f32; 3]; 4] = [[50.0, 0.0, 0.0], [0.0, 10.0, 10.0], [0.0, 0.0, 80.0], [5.0, 5.0, 0.0]];
            C[((x / 8) % 4) as usize]
        }
    })
}

/// Smooth value noise in [0, 1): bilinear-smoothstep interpolation of hashed lattice values.
fn value_noise(seed: u64, x: f32, y: f32) -> f32 {
    let lattice = |ix: i64, iy: i64| {
        let h = mix64(seed ^ mix64((ix as u64) ^ mix64(iy as u64).rotate_left(17)));
        (h >> 40) as f32 / (1u64 << 24) as f32
    };
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let smooth = |t: f32| t * t * (3.0 - 2.0 * t);
    let (tx, ty) = (smooth(x - fx), smooth(y - fy));
    let top = lattice(ix, iy) + (lattice(ix + 1, iy) - lattice(ix, iy)) * tx;
    let bottom = lattice(ix, iy + 1) + (lattice(ix + 1, iy + 1) - lattice(ix, iy + 1)) * tx;
    top + (bottom - top) * ty
}

/// Number of highlights in `specular`.
const HIGHLIGHTS: usize = 40;

fn specular() -> HdrImage {
    let (w, h) = (512u32, 512u32);
    let mut rng = SplitMix64::new(0x5BEC);
    // Highlights: centre, sigma (px), peak (units: 50-300, i.e. 5e3-3e4 nits).
    let spots: Vec<(f32, f32, f32, f32)> = (0..HIGHLIGHTS)
        .map(|_| {
            let x = rng.next_f64() as f32 * w as f32;
            let y = rng.next_f64() as f32 * h as f32;
            let sigma = 0.7 + 2.3 * rng.next_f64() as f32;
            let peak = 50.0 + 250.0 * rng.next_f64() as f32;
            (x, y, sigma, peak)
        })
        .collect();
    build(w, h, ColorPrimaries::Bt709, |x, y| {
        let (fx, fy) = (x as f32, y as f32);
        let mut n = 0.0;
        let mut amp = 0.5;
        let mut freq = 1.0 / 32.0;
        for octave in 0..4u64 {
            n += amp * value_noise(0xA1BE00 + octave, fx * freq, fy * freq);
            amp *= 0.5;
            freq *= 2.0;
        }
        // n is in [0, 0.9375): base light 0.3-1.5 units with a warm/cool albedo swing.
        let base = 0.3 + 1.28 * n;
        let tint = value_noise(0x7147, fx / 64.0, fy / 64.0);
        let mut c = [base * (0.8 + 0.4 * tint), base, base * (1.2 - 0.4 * tint)];
        for &(sx, sy, sigma, peak) in &spots {
            let d2 = (fx + 0.5 - sx).powi(2) + (fy + 0.5 - sy).powi(2);
            if d2 < 25.0 * sigma * sigma {
                c = add3(c, scale3([1.0, 0.97, 0.9], peak * (-d2 / (2.0 * sigma * sigma)).exp()));
            }
        }
        c
    })
}

fn tiny_1x1() -> HdrImage {
    build(1, 1, ColorPrimaries::Bt709, |_, _| [60.0, 30.0, 5.0])
}

fn odd_3x5() -> HdrImage {
    let mut rng = SplitMix64::new(0x0335);
    // Log-uniform over 1e-4..1e3 units (0.01-1e5 nits), each channel on its own.
    build(3, 5, ColorPrimaries::Bt709, |_, _| {
        let mut c = [0.0f32; 3];
        for v in &mut c {
            *v = 10f64.powf(-4.0 + 7.0 * rng.next_f64()) as f32;
        }
        c
    })
}

fn odd_257x129() -> HdrImage {
    let (w, h) = (257u32, 129u32);
    let mut rng = SplitMix64::new(0x257_129);
    build(w, h, ColorPrimaries::Bt709, |x, y| {
        let dx = (x as f32 - 128.0) / 128.0;
        let dy = (y as f32 - 64.0) / 64.0;
        let r = (dx * dx + dy * dy).sqrt().min(1.5) / 1.5;
        // 1e4 nits in the centre falling to 1 nit at the corners, ±5 % noise.
        let v = 10f32.powf(2.0 - 4.0 * r) * (1.0 + 0.05 * rng.gaussian() as f32);
        [v, v * 0.8, v * 0.6]
    })
}

fn alpha() -> HdrImage {
    let (w, h) = (200u32, 150u32);
    build(w, h, ColorPrimaries::Bt709, |x, y| {
        // Hue sweep across x, brightness 0.1-20 units across y (log).
        let hue = x as f32 / w as f32 * 6.0;
        let rgb =
            [(hue - 3.0).abs() - 1.0, 2.0 - (hue - 2.0).abs(), 2.0 - (hue - 4.0).abs()].map(|v| v.clamp(0.05, 1.0));
        let level = 10f32.powf(-1.0 + 2.3 * y as f32 / (h - 1) as f32);
        // Alpha: a soft disk (1 inside r=50, linear fall to 0 by r=60), a 0.5 stripe on top.
        let d = ((x as f32 - 100.0).powi(2) + (y as f32 - 80.0).powi(2)).sqrt();
        let mut a = ((60.0 - d) / 10.0).clamp(0.0, 1.0);
        if y < 12 {
            a = 0.5;
        }
        let [r, g, b] = scale3(rgb, level);
        [r, g, b, a]
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lum_nits(img: &HdrImage) -> Vec<f64> {
        // luminance() is in nits already.
        luminance(img)
    }

    #[test]
    fn generation_is_deterministic() {
        let a: Vec<u64> = scenes().iter().map(|s| sample_hash(&s.image)).collect();
        let b: Vec<u64> = scenes().iter().map(|s| sample_hash(&s.image)).collect();
        assert_eq!(a, b);
        // And every scene differs from every other.
        let mut sorted = a.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), a.len());
    }

    #[test]
    fn all_samples_are_finite_and_non_negative() {
        for s in scenes() {
            assert!(s.image.samples().iter().all(|v| v.is_finite() && *v >= 0.0), "{}", s.name);
        }
    }

    #[test]
    fn largest_scene_is_modest() {
        for s in scenes() {
            assert!(s.image.pixel_count() <= 512 * 512, "{} is too large for a quick bench", s.name);
        }
    }

    #[test]
    fn sun_peaks_above_1e5_nits_over_a_much_dimmer_sky() {
        let img = scene("sun-sky").unwrap().image;
        let lum = lum_nits(&img);
        let peak = lum.iter().copied().fold(0.0, f64::max);
        assert!(peak >= 1e5, "sun peak {peak} nits");
        // Sky at the top-left corner, far from the sun: between 500 and 5000 nits.
        assert!((500.0..5000.0).contains(&lum[0]), "sky {} nits", lum[0]);
        // The disk (radius 10 px, about 314 px) is small: under 0.5 % of pixels above 1e4 nits.
        let bright = lum.iter().filter(|&&l| l > 1e4).count();
        assert!(bright > 200 && bright * 200 < lum.len(), "{bright} pixels above 1e4 nits");
    }

    #[test]
    fn bt2020_ramps_are_pure_primaries_outside_bt709() {
        let img = scene("bt2020-ramps").unwrap().image;
        assert_eq!(img.color.primaries, ColorPrimaries::Bt2020);
        // Every pixel of a band has exactly the band's zero channels.
        let band = img.height() / 6;
        for y in 0..img.height() {
            let pure = PURE[(y / band) as usize];
            for x in 1..img.width() {
                let p = img.pixel(x, y);
                for c in 0..3 {
                    assert_eq!(p[c] == 0.0, pure[c] == 0.0, "({x},{y}) {p:?}");
                }
            }
        }
        // BT.2020 green expressed in BT.709 needs negative red and blue: out of BT.709 gamut.
        let as709 = hdrcodec::core::color::convert_primaries(&img, ColorPrimaries::Bt709);
        let out_of_gamut = as709.samples().iter().filter(|&&v| v < 0.0).count();
        assert!(out_of_gamut * 3 > as709.samples().len() / 3, "{out_of_gamut} negative samples");
        // Log rows span 0.1 .. 1e4 nits for the green band (luminance of pure BT.2020 green).
        let lum = lum_nits(&img);
        let peak = lum.iter().copied().fold(0.0, f64::max);
        assert!(peak > 5e3, "peak {peak}");
    }

    #[test]
    fn dark_region_mean_is_1e_minus_3_nits() {
        let img = scene("dark-noise").unwrap().image;
        let lum = lum_nits(&img);
        let w = img.width() as usize;
        let left: Vec<f64> = lum.chunks(w).flat_map(|row| row[..w / 2].to_vec()).collect();
        let mean = left.iter().sum::<f64>() / left.len() as f64;
        assert!((mean - 1e-3).abs() < 0.05e-3, "dark mean {mean} nits");
        // It is noisy: the coefficient of variation is about that of the lognormal (σ = 0.5).
        let var = left.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / left.len() as f64;
        let cv = var.sqrt() / mean;
        assert!((0.4..0.7).contains(&cv), "coefficient of variation {cv}");
    }

    #[test]
    fn edges_have_a_million_to_one_steps() {
        let img = scene("edges").unwrap().image;
        let lum = lum_nits(&img);
        let w = img.width() as usize;
        let steps = lum
            .windows(2)
            .enumerate()
            .filter(|(i, p)| (i + 1) % w != 0 && p[0].max(p[1]) >= 1e6 * p[0].min(p[1]) * 0.99);
        assert!(steps.count() > 1000);
    }

    #[test]
    fn specular_highlights_are_sharp_and_sparse() {
        let img = scene("specular").unwrap().image;
        let lum = lum_nits(&img);
        let peak = lum.iter().copied().fold(0.0, f64::max);
        assert!(peak >= 5e3, "highlight peak {peak}");
        let above = lum.iter().filter(|&&l| l > 1000.0).count();
        assert!(above * 50 < lum.len(), "{above} bright pixels");
        let mut sorted = lum.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        assert!((30.0..150.0).contains(&median), "median {median}");
    }

    #[test]
    fn odd_sizes_and_alpha() {
        let dims = |n: &str| {
            let i = scene(n).unwrap().image;
            (i.width(), i.height(), i.channels())
        };
        assert_eq!(dims("tiny-1x1"), (1, 1, Channels::Rgb));
        assert_eq!(dims("odd-3x5"), (3, 5, Channels::Rgb));
        assert_eq!(dims("odd-257x129"), (257, 129, Channels::Rgb));
        let img = scene("alpha").unwrap().image;
        assert_eq!(img.channels(), Channels::Rgba);
        let alphas: Vec<f32> = img.samples().chunks(4).map(|p| p[3]).collect();
        assert!(alphas.iter().all(|a| (0.0..=1.0).contains(a)));
        assert!(alphas.contains(&0.0) && alphas.contains(&1.0) && alphas.contains(&0.5));
        assert!(alphas.iter().any(|&a| a > 0.05 && a < 0.45), "soft edge");
    }

    #[test]
    fn manifest_has_a_line_per_scene() {
        let m = manifest(&scenes());
        assert_eq!(m.lines().count(), SCENES.len() + 1);
        assert!(m.lines().all(|l| l.split('\t').count() == 10));
    }
}
