#!/usr/bin/env python3
"""A quick look at a recovered MERL table against an independent scene's truth, at the truth's
subset of bins (truth_subset.bin), by theta_d band: the cosine-weighted relative error
sqrt(sum (c (f_rec - f_true))^2 / sum (c f_true)^2), c = cos theta_i cos theta_o at the bin
centre, the median and largest f_rec / f_true. A table figure, secondary to rendered errors
(docs/error-metrics.md); bins where the result has no data count as zero. Needs numpy only.

    python3 scripts/independent/table_error.py SCENE_DIR OUT/brdf.binary
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from independent.merl import SCALES, SUBSET_MAGIC, SUBSET_RECORD  # noqa: E402

BANDS_DEG = [(0, 90), (0, 25), (25, 50), (50, 70), (70, 90)]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    scene, result = sys.argv[1:]
    raw = open(os.path.join(scene, "truth_subset.bin"), "rb").read()
    if raw[:8] != SUBSET_MAGIC:
        sys.exit(f"{scene}/truth_subset.bin: not a truth subset")
    truth = np.frombuffer(raw[16:], dtype=SUBSET_RECORD)
    table = np.fromfile(result, dtype="<f8", offset=12).reshape(3, -1)
    rec = (table[:, truth["index"]] * SCALES[:, None]).T
    rec = np.where(rec < 0, 0.0, rec)
    true = truth["rgb"].astype(np.float64)
    w = (truth["cos_i"] * truth["cos_o"]).astype(np.float64)[:, None]
    theta_d = (truth["index"] // 180) % 90  # bin index = degrees
    print(f"{result} against {scene} ({len(truth)} bins)")
    for lo, hi in BANDS_DEG:
        s = (theta_d >= lo) & (theta_d < hi)
        err = np.sqrt(((w * (rec - true))[s] ** 2).sum() / ((w * true)[s] ** 2).sum())
        ratio = rec[s] / np.maximum(true[s], 1e-12)
        print(f"  theta_d {lo:2d}-{hi:2d} deg: {s.sum():5d} bins, cosine-weighted error "
              f"{err:9.3f}, median rec/true {np.median(ratio):8.3f}, max {ratio.max():10.1f}")


if __name__ == "__main__":
    main()
