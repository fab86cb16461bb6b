"""Does the deblurring's gain follow the normals' residual error? Per scene of two runs of the
same accuracy grid (`bench accuracy ... --refine-normals`, once as released and once with
`--deblur SIGMA`): the gain in the rendered ratio (better analytic baseline's environment error
over ours) against the median normal error after the refinement, at the pixels and at the
vertices; the rank correlations, and the gain's geometric mean per material.

Usage: python3 scripts/deblur_vs_normals.py RELEASED/accuracy.json DEBLURRED/accuracy.json
"""
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from heldout_vs_render import spearman  # noqa: E402


def load(path):
    out = {}
    for s in json.load(open(path))['scenes']:
        v = s['variants'][0][1]
        if 'Ok' not in v or not s.get('normals'):
            continue
        base = min(s['lambert']['environment'], s['lambert_ggx']['environment'])
        key = (s['material'], s['mesh'], s['rig']['kind'], s['seed'])
        out[key] = (base / v['Ok']['chosen']['environment'],
                    s['normals']['pixel_median_after_deg'], s['normals']['median_after_deg'])
    return out


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    a, b = load(sys.argv[1]), load(sys.argv[2])
    keys = [k for k in a if k in b]
    gain = [math.log(b[k][0] / a[k][0]) for k in keys]
    print('scenes %d; pixels\' residual error %.2f-%.2f deg' % (
        len(keys), min(a[k][1] for k in keys), max(a[k][1] for k in keys)))
    print('rank correlation of the gain with the pixels\' error %.2f, the vertices\' %.2f' % (
        spearman([a[k][1] for k in keys], gain), spearman([a[k][2] for k in keys], gain)))
    for m in sorted({k[0] for k in keys}):
        g = [x for k, x in zip(keys, gain) if k[0] == m]
        print('  %-14s gain gm %.2f over %d' % (m, math.exp(sum(g) / len(g)), len(g)))


if __name__ == '__main__':
    main()
