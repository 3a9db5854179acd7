#!/usr/bin/env python3
"""Our gain-map JPEG rows against libultrahdr's at equal size, from `hdrcodec bench --json`.

For each of our `ultrahdr:qNN` rows, libultrahdr's PU21-PSNR and mean ΔE ITP on the same image
are interpolated linearly in log bits per pixel between its two nearest rows
(`ultrahdr(libultrahdr):qNN`); a row outside libultrahdr's range of sizes is counted, not
scored. Prints one line per point and the summary the crate README quotes.

Usage: gainmap_equal_size.py BENCH.json [OTHER.json ...]   (rows of several runs are pooled;
a later file's row replaces an earlier one's of the same image and configuration)
"""
import json
import math
import sys


def main():
    rows = {}
    for path in sys.argv[1:]:
        for r in json.load(open(path))["rows"]:
            if r.get("error") is None and r["config"].startswith("ultrahdr"):
                rows[(r["image"], r["config"])] = r
    images = sorted({i for i, _ in rows})
    dpsnr, dde, outside = [], [], 0
    for image in images:
        theirs = sorted(
            (math.log(r["bpp"]), r["pu21_psnr"], r["de_itp_mean"])
            for (i, c), r in rows.items()
            if i == image and c.startswith("ultrahdr(libultrahdr):")
        )
        ours = sorted(
            (r["config"], r) for (i, c), r in rows.items() if i == image and c.startswith("ultrahdr:")
        )
        for config, r in ours:
            x = math.log(r["bpp"])
            pair = [(a, b) for a, b in zip(theirs, theirs[1:]) if a[0] <= x <= b[0]]
            if not pair:
                outside += 1
                print(f"{image}\t{config}\t{r['bpp']:.3f} bpp\toutside libultrahdr's sizes")
                continue
            a, b = pair[0]
            t = (x - a[0]) / (b[0] - a[0])
            p = a[1] + t * (b[1] - a[1])
            d = a[2] + t * (b[2] - a[2])
            dpsnr.append(r["pu21_psnr"] - p)
            dde.append(r["de_itp_mean"] - d)
            print(
                f"{image}\t{config}\t{r['bpp']:.3f} bpp\tPU21 {r['pu21_psnr']:.2f} vs {p:.2f} ({dpsnr[-1]:+.2f})"
                f"\tdE ITP {r['de_itp_mean']:.2f} vs {d:.2f} ({dde[-1]:+.2f})"
            )
    if dpsnr:
        print(
            f"{len(dpsnr)} points ({outside} outside): PU21-PSNR {sum(dpsnr) / len(dpsnr):+.2f} dB on average, "
            f"{min(dpsnr):+.2f} at worst; dE ITP {sum(dde) / len(dde):+.2f} on average, {max(dde):+.2f} at worst"
        )


if __name__ == "__main__":
    main()
