#!/usr/bin/env python3
"""Where our gain-map JPEG's SDR base and HDR rendition lose, stage by stage (issue #13).

A numpy model of `codecs/jpeghdr/src/encode.rs` (the default gain-map encoder: GT curve with a
linear toe on luminance, bright colours desaturated or kept, log2 gain averaged over a half-size
map, each map pixel raised to what the base pixels of its bilinear reach need to fit under 1.0,
codes between the measured range, base corrected for the map as decoded, offsets 1/256), written
independently of the Rust code so that each stage can be switched off and scored alone. JPEG
coding is libjpeg's (imagecodecs), not the encoder's jpeg-encoder: compare stages, not bytes.

  tmqi   SOURCE NITS   TMQI (scripts/tmqi.py) of the tone-mapped image alone, of the base
                       pre-corrected without the raise, and of the base as the encoder makes it.
  darks  SOURCE NITS   ΔE ITP (BT.2124) of the HDR rendition, over all pixels and over those
                       under 0.1 cd/m², after each stage: map codes quantised (and JPEG-coded at
                       quality 90), base quantised to 8-bit sRGB, base JPEG-coded at quality 90
                       (4:4:4); for bright_colours=desaturate and =keep.

Run with the reference venv's Python (numpy, imagecodecs, OpenImageIO).
"""
import os
import sys

import imagecodecs
import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tmqi import tmqi  # noqa: E402

K = 1 / 256  # the encoder's offsets, base and alternate
WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


def load(path):
    hdr = oiio.ImageBuf(path).get_pixels(oiio.FLOAT)[..., :3].astype(np.float64)
    return np.nan_to_num(hdr, nan=0.0, posinf=0.0).clip(0, None)


def srgb_codes(linear):
    v = np.clip(linear, 0, 1)
    return np.round(255 * np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)).astype(np.uint8)


def srgb_linear(codes):
    c = codes.astype(np.float64) / 255
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def gt_linear_toe(x):
    """GT tone curve, P = 1, a = 1, m = 0.22, l = 0.4, black tightness 1 (the encoder's base_curve)."""
    p, a, m, l = 1.0, 1.0, 0.22, 0.4
    l0 = (p - m) * l / a
    s0, s1 = m + l0, m + a * l0
    t = np.clip(x / m, 0, 1)
    toe_w = 1 - t * t * (3 - 2 * t)
    shoulder_w = (x >= s0).astype(float)
    linear = m + a * (x - m)
    shoulder = p - (p - s1) * np.exp(-a / (p - s1) * (x - s0))
    return x * toe_w + linear * (1 - toe_w - shoulder_w) + shoulder * shoulder_w


def tone_map(rgb, keep):
    y = np.maximum(rgb @ WEIGHTS, 0)
    t = np.minimum(gt_linear_toe(y), 1.0)
    ratio = np.where(y > 1e-12, t / np.maximum(y, 1e-12), 0)
    if keep:
        hi = rgb.max(-1)
        return np.clip(rgb * np.minimum(ratio, 1 / np.maximum(hi, 1e-12))[..., None], 0, 1)
    return into_unit_cube(rgb * ratio[..., None], t)


def into_unit_cube(rgb, y):
    y = np.clip(y, 0, 1)[..., None]
    hi, lo = rgb.max(-1, keepdims=True), rgb.min(-1, keepdims=True)
    s = np.ones_like(hi)
    s = np.where(hi > 1, np.minimum(s, (1 - y) / np.maximum(hi - y, 1e-12)), s)
    s = np.where(lo < 0, np.minimum(s, y / np.maximum(y - lo, 1e-12)), s)
    return np.clip(y + (rgb - y) * np.maximum(s, 0), 0, 1)


def box_matrix(n, map_n):
    """Map pixel m averages a box one map pixel wide centred on base coordinate m · n / map_n."""
    spacing = n / map_n
    a = np.zeros((map_n, n))
    for x in range(n):
        lo, hi = x - 0.5, x + 0.5
        first = max(int(np.ceil((lo - spacing / 2) / spacing)), 0)
        last = min(int(np.floor((hi + spacing / 2) / spacing)), map_n - 1)
        for m in range(first, last + 1):
            overlap = min(hi, m * spacing + spacing / 2) - max(lo, m * spacing - spacing / 2)
            if overlap > 1e-9:
                a[m, x] += overlap
    return a / a.sum(1, keepdims=True)


def upsample_matrix(n, map_n):
    """Decoders' bilinear upsampling: base pixel x samples the map at x · map_n / n."""
    pos = np.minimum(np.arange(n) * map_n / n, map_n - 1)
    i0 = np.floor(pos).astype(int)
    i1, f = np.minimum(i0 + 1, map_n - 1), pos - i0
    u = np.zeros((n, map_n))
    u[np.arange(n), i0] += 1 - f
    u[np.arange(n), i1] += f
    return u, i0


def per_channel(matrix_left, planes, matrix_right):
    return np.stack([matrix_left @ planes[..., c] @ matrix_right.T for c in range(3)], -1)


def encode(rgb, sdr, scale=2, raise_to_fit=True, correct=True, map_quality=None):
    """The base (linear) and the gain decoders apply, as the encoder makes them."""
    h, w, _ = rgb.shape
    mh, mw = -(-h // scale), -(-w // scale)
    gains = per_channel(box_matrix(h, mh), np.log2((rgb + K) / (sdr + K)), box_matrix(w, mw))
    (ux, ix), (uy, iy) = upsample_matrix(w, mw), upsample_matrix(h, mh)
    if raise_to_fit:
        # The encoder's rule: each map pixel at least the largest need of the base pixels whose
        # lower map neighbours are it or the pixel before it, on each axis.
        need = np.log2((rgb + K) / (1 + K))
        cell = np.full((mh, mw, 3), -np.inf)
        rows, cols = np.meshgrid(iy, ix, indexing="ij")
        for c in range(3):
            np.maximum.at(cell[..., c], (rows, cols), need[..., c])
        floor = cell.copy()
        floor[1:] = np.maximum(floor[1:], cell[:-1])
        floor[:, 1:] = np.maximum(floor[:, 1:], floor[:, :-1].copy())
        gains = np.maximum(gains, floor)
    lo, hi = gains.min((0, 1)), gains.max((0, 1))
    codes = np.round(255 * (gains - lo) / (hi - lo))
    if map_quality:
        coded = imagecodecs.jpeg8_encode(codes.astype(np.uint8), level=map_quality, subsampling=(1, 1))
        codes = imagecodecs.jpeg8_decode(coded).astype(np.float64)
    gain = 2 ** (lo + (hi - lo) * per_channel(uy, codes, ux) / 255)
    if not correct:
        return sdr, gain
    base = np.maximum((rgb + K) / gain - K, 0)
    return into_unit_cube(base, base @ WEIGHTS), gain


def ictcp(rgb709_nits):
    to2020 = np.array([[0.6274, 0.3293, 0.0433], [0.0691, 0.9195, 0.0114], [0.0164, 0.0880, 0.8956]])
    lms = np.array([[1688, 2146, 262], [683, 2951, 462], [99, 309, 3688]]) / 4096
    m1, m2, c1, c2, c3 = 2610 / 16384, 2523 / 4096 * 128, 3424 / 4096, 2413 / 4096 * 32, 2392 / 4096 * 32
    y = np.clip(rgb709_nits @ to2020.T @ lms.T / 10000, 0, None) ** m1
    pq = ((c1 + c2 * y) / (1 + c3 * y)) ** m2
    to_ictcp = np.array([[0.5, 0.5, 0], [6610 / 4096, -13613 / 4096, 7003 / 4096], [17933 / 4096, -17390 / 4096, -543 / 4096]])
    return pq @ to_ictcp.T


def delta_e_itp(a_nits, b_nits):
    d = ictcp(a_nits) - ictcp(b_nits)
    return 720 * np.sqrt(d[..., 0] ** 2 + (0.5 * d[..., 1]) ** 2 + d[..., 2] ** 2)


def tmqi_stages(hdr, rgb):
    sdr = tone_map(rgb, keep=False)
    for name, kwargs in [("tone-mapped only", dict(correct=False)), ("pre-corrected, no raise", dict(raise_to_fit=False)), ("as encoded", {})]:
        base, _ = encode(rgb, sdr, **kwargs)
        q, s, n = tmqi(hdr, srgb_codes(base))
        print(f"  {name:24s} TMQI {q:.4f}  S {s:.4f}  N {n:.4f}  mean code {srgb_codes(base).mean():.1f}")


def dark_stages(hdr, rgb, nits):
    reference = rgb * 203
    dark = (hdr @ WEIGHTS) * nits < 0.1
    print(f"  pixels under 0.1 cd/m²: {dark.mean() * 100:.0f} %")
    for keep in [False, True]:
        base, gain = encode(rgb, tone_map(rgb, keep), map_quality=90)
        codes = srgb_codes(base)
        decoded = imagecodecs.jpeg8_decode(imagecodecs.jpeg8_encode(codes, level=90, subsampling=(1, 1)))
        print(f"  bright_colours={'keep' if keep else 'desaturate'}: mean log2 gain in the darks {np.log2(gain[dark]).mean(0).round(4)}")
        for stage, linear in [("map coded", base), ("+ 8-bit sRGB base", srgb_linear(codes)), ("+ base JPEG q90", srgb_linear(decoded))]:
            e = delta_e_itp(reference, ((linear + K) * gain - K) * 203)
            print(f"    {stage:20s} ΔE ITP {e.mean():6.2f}   under 0.1 cd/m² {e[dark].mean():6.2f}   above {e[~dark].mean():6.2f}")


def main():
    what, src, nits = sys.argv[1], sys.argv[2], float(sys.argv[3])
    hdr = load(src)
    rgb = hdr * nits / 203
    print(src.split("/")[-1])
    {"tmqi": lambda: tmqi_stages(hdr, rgb), "darks": lambda: dark_stages(hdr, rgb, nits)}[what]()


if __name__ == "__main__":
    main()
