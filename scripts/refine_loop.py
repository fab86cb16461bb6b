#!/usr/bin/env python3
"""The normal refinement's study loop (docs/normal-refinement.md, "Session 41").

Runs `examples/refine_study` over 4 materials x Spot, Bunny x spread, one light at 30 degrees
x seeds, at 320x240, for each VARIANT (study keys, `""` the defaults), and prints per rig and
material, then over every scene, the geometric mean of the median vertex-normal error after /
before and the mean held-out error after the last alternation tried (the one that stopped
the refinement, or the last allowed).

    cargo build --release --example refine_study
    python3 scripts/refine_loop.py [--seeds 0,1,2] [--scene scene:views=21] VARIANT...

Simulated scenes with neural fits of MERL materials as the truth (Sztrajman et al. 2021:
approximations of the MERL measurements, not measured MERL data).
"""
import argparse
import math
import re
import subprocess
import sys
from collections import defaultdict

MATERIALS = ["fruitwood-241", "blue-acrylic", "alum-bronze", "pink-fabric"]
LINE = re.compile(
    r'^"(.*)": .*normal error median ([\d.]+) -> ([\d.]+).*train/held (.*?), [\d.]+ s'
)


def gm(xs):
    return math.exp(sum(map(math.log, xs)) / len(xs)) if xs else float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--study", default="target/release/examples/refine_study")
    ap.add_argument("--scene", default=None, help="a `scene:KEY=VALUE,...` argument")
    ap.add_argument("variants", nargs="*", default=[""])
    a = ap.parse_args()
    ratio = defaultdict(list)
    held = defaultdict(list)
    for m in MATERIALS:
        for mesh in ["spot", "bunny"]:
            for rig in ["spread", "one30"]:
                for seed in a.seeds.split(","):
                    cmd = [a.study, m, mesh, rig, "320x240", seed]
                    if a.scene:
                        cmd.append(a.scene)
                    cmd += a.variants
                    out = subprocess.run(cmd, capture_output=True, text=True)
                    if out.returncode != 0:
                        sys.exit(f"{' '.join(cmd)}: {out.stderr.strip()}")
                    for line in out.stdout.splitlines():
                        g = LINE.match(line)
                        if not g:
                            continue
                        var, before, after, its = g.groups()
                        last = float(its.split()[-1].split("/")[1])
                        ratio[(var, rig, m)].append(float(after) / float(before))
                        held[(var, rig, m)].append(last)
    variants = sorted({k[0] for k in ratio})
    for rig in ["spread", "one30"]:
        for m in MATERIALS:
            cells = [
                f"{v or 'defaults'}: {gm(ratio[(v, rig, m)]):.3f} / {sum(held[(v, rig, m)]) / len(held[(v, rig, m)]):.3f}"
                for v in variants
            ]
            print(f"{rig:7s} {m:14s} " + "  ".join(cells))
    for v in variants:
        xs = [x for k, r in ratio.items() if k[0] == v for x in r]
        print(f"{v or 'defaults'}: vertex error after / before, gm over {len(xs)} scenes: {gm(xs):.3f}")


if __name__ == "__main__":
    main()
