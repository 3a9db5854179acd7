#!/usr/bin/env python3
"""TMQI (Yeganeh & Wang, "Objective Quality Assessment of Tone-Mapped Images", IEEE TIP 22(2),
2013) of the SDR base images of gain-map JPEGs against their HDR source, written here from the
paper's formulas with numpy only (no scipy), independently of hdrcodec's code. Not checked
against the authors' MATLAB numbers: use it to rank two tone mappings of the same image.

Q = a·S^alpha + (1 − a)·N^beta, a = 0.8012, alpha = 0.3046, beta = 0.7088
S: structural fidelity, 5 scales (weights 0.0448 0.2856 0.3001 0.2363 0.1333; spatial
   frequencies 16 … 1 cycles/degree), 11×11 Gaussian window (σ 1.5), local standard deviations
   mapped through a normal CDF centred on the CSF's visibility threshold (Mannos–Sakrison form).
N: statistical naturalness, the SDR image's mean (Gaussian, 115.94 ± 27.99) and mean 11×11 block
   standard deviation (Beta(4.4, 10.1) of sd/64.29), each normalised by its peak.

Usage: tmqi.py HDR_SOURCE NITS_PER_UNIT OURS.jpg [...]   (the venv's Python: OpenImageIO, imagecodecs)
Also encodes the source with libultrahdr 1.4 (imagecodecs.ultrahdr_encode, level 90) and scores
its base the same way.
"""
import math
import sys

import imagecodecs
import numpy as np
import OpenImageIO as oiio


def luminance(rgb):
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


def gaussian_window(size=11, sigma=1.5):
    x = np.arange(size) - (size - 1) / 2
    g = np.exp(-(x**2) / (2 * sigma**2))
    return g / g.sum()


def filter_valid(img, g):
    """Separable 'valid' correlation with the 1-D kernel g on both axes."""
    k = len(g)
    rows = sum(g[i] * img[:, i : img.shape[1] - k + 1 + i] for i in range(k))
    return sum(g[i] * rows[i : rows.shape[0] - k + 1 + i, :] for i in range(k))


def normal_cdf(x, mu, sigma):
    # Abramowitz & Stegun 7.1.26 for erf (|error| < 1.5e-7).
    z = (x - mu) / (sigma * math.sqrt(2.0))
    s = np.sign(z)
    z = np.abs(z)
    t = 1.0 / (1.0 + 0.3275911 * z)
    poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))))
    erf = s * (1.0 - poly * np.exp(-z * z))
    return 0.5 * (1.0 + erf)


def local_fidelity(hdr, ldr, frequency):
    g = gaussian_window()
    mu1, mu2 = filter_valid(hdr, g), filter_valid(ldr, g)
    s1 = np.sqrt(np.maximum(filter_valid(hdr * hdr, g) - mu1 * mu1, 0))
    s2 = np.sqrt(np.maximum(filter_valid(ldr * ldr, g) - mu2 * mu2, 0))
    s12 = filter_valid(hdr * ldr, g) - mu1 * mu2
    csf = 100.0 * 2.6 * (0.0192 + 0.114 * frequency) * math.exp(-((0.114 * frequency) ** 1.1))
    threshold = 128 / (1.4 * csf)
    p1 = normal_cdf(s1, threshold, threshold / 3)
    p2 = normal_cdf(s2, threshold, threshold / 3)
    c1, c2 = 0.01, 10.0
    m = (2 * p1 * p2 + c1) / (p1 * p1 + p2 * p2 + c1) * (s12 + c2) / (s1 * s2 + c2)
    return m.mean()


def halve(img):
    h, w = img.shape[0] // 2 * 2, img.shape[1] // 2 * 2
    img = img[:h, :w]
    return (img[0::2, 0::2] + img[1::2, 0::2] + img[0::2, 1::2] + img[1::2, 1::2]) / 4


def structural_fidelity(hdr, ldr):
    weights = [0.0448, 0.2856, 0.3001, 0.2363, 0.1333]
    s = 1.0
    for level, w in enumerate(weights):
        s *= local_fidelity(hdr, ldr, 16 / 2**level) ** w
        hdr, ldr = halve(hdr), halve(ldr)
    return s


def beta_pdf(x, a, b):
    return math.exp((a - 1) * math.log(x) + (b - 1) * math.log(1 - x) + math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b))


def naturalness(ldr):
    mean = ldr.mean()
    h, w = ldr.shape[0] // 11 * 11, ldr.shape[1] // 11 * 11
    blocks = ldr[:h, :w].reshape(h // 11, 11, w // 11, 11)
    sd = blocks.std(axis=(1, 3), ddof=1).mean()
    pm = math.exp(-((mean - 115.94) ** 2) / (2 * 27.99**2))
    x = min(max(sd / 64.29, 1e-9), 1 - 1e-9)
    mode = (4.4 - 1) / (4.4 + 10.1 - 2)
    return pm * beta_pdf(x, 4.4, 10.1) / beta_pdf(mode, 4.4, 10.1)


def tmqi(hdr_rgb, ldr_rgb8):
    lh = luminance(hdr_rgb.astype(np.float64))
    lh = np.round((2**32 - 1) / (lh.max() - lh.min())) * (lh - lh.min())
    ll = luminance(ldr_rgb8.astype(np.float64))
    s, n = structural_fidelity(lh, ll), naturalness(ll)
    return 0.8012 * s**0.3046 + (1 - 0.8012) * n**0.7088, s, n


def base_of(jpeg):
    """The primary image of a gain-map JPEG (libjpeg through imagecodecs reads the first)."""
    return imagecodecs.jpeg8_decode(jpeg)[..., :3]


def main():
    src, nits = sys.argv[1], float(sys.argv[2])
    img = oiio.ImageBuf(src)
    hdr = img.get_pixels(oiio.FLOAT)[..., :3]
    hdr = np.nan_to_num(hdr, nan=0.0, posinf=0.0).clip(0, None)
    rgba = np.concatenate([hdr * nits / 203.0, np.ones(hdr.shape[:2] + (1,), np.float32)], axis=2)
    theirs = imagecodecs.ultrahdr_encode(rgba.clip(0, 65504).astype(np.float16), level=90)
    for name, data in [("libultrahdr", theirs)] + [(p, open(p, "rb").read()) for p in sys.argv[3:]]:
        q, s, n = tmqi(hdr, base_of(data))
        print(f"{src.split('/')[-1]}\t{name}\tTMQI {q:.4f}\tS {s:.4f}\tN {n:.4f}")


if __name__ == "__main__":
    main()
