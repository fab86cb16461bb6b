#!/usr/bin/env python3
"""The found materials of a `brdf-rig bench materials` page against the bar, and how much the
bar itself moves between seeds of the same object (docs/materials.md, session 56).

Reads DIR/materials.json (`bench materials --out DIR`); only objects of two or more materials.
The bar of a found material is the better of Lambert and Lambert + GGX fitted to the same
pixels (environment error); "worse" is ours above 1.1 times the bar, the criterion of issue #17
(the page's own summary, DIR/materials.md, gives the ratio's geometric mean and the count).
Prints the losses by name, and per object, rig and true material (a group): whether our
geometric mean over the seeds is worse than the bar's by > 10 %, and the bar's largest /
smallest over the seeds, largest first. Standard library only.

usage: scripts/bar_spread.py DIR/materials.json [ROWS]
"""
import json
import math
import sys
from collections import defaultdict


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__.strip().splitlines()[-1])
    path = sys.argv[1]
    try:
        rows = int(sys.argv[2]) if len(sys.argv) == 3 else 10
    except ValueError:
        sys.exit(f"ROWS {sys.argv[2]!r}: not a count")
    try:
        with open(path) as f:
            page = json.load(f)
    except (OSError, ValueError) as e:
        sys.exit(f"{path}: {e}")
    try:
        losses, groups = read_page(page)
    except (KeyError, TypeError, AttributeError) as e:
        sys.exit(f"{path}: not a `bench materials` page (missing or malformed field {e})")
    if not groups:
        sys.exit(f"{path}: no object of two or more materials")
    print(f"found materials worse than the bar by > 10 %: {len(losses)}")
    for mesh, rig, seed, truth, model, ours, bar in losses:
        print(f"  {mesh} {rig} seed {seed} {truth} ({model}): ours {ours:.3f}, bar {bar:.3f}")
    report_groups(groups, rows)


def usable(x):
    """A positive, finite error (the page writes NaN where a material had no truth)."""
    return isinstance(x, (int, float)) and math.isfinite(x) and x > 0


def read_page(page):
    """The losses, and the (seed, bar, ours) of each group."""
    losses = []
    groups = defaultdict(list)
    for o in page.get("objects", []):
        if o.get("count", 0) < 2:
            continue
        for s in o.get("scores", []):
            baselines = [b for b in (s.get("lambert"), s.get("lambert_ggx")) if usable(b)]
            if not baselines or not usable(s.get("ours")):
                continue  # a material without a baseline or a score is not judged
            bar = min(baselines)
            key = (o["mesh"], "+".join(o["materials"]), o["rig"]["kind"], s["truth"])
            groups[key].append((o["seed"], bar, s["ours"]))
            if s["ours"] > 1.1 * bar:
                losses.append((o["mesh"], o["rig"]["kind"], o["seed"], s["truth"], s["model"],
                               s["ours"], bar))
    return losses, groups


def report_groups(groups, rows):
    """Each group's geometric means over its seeds, and the bar's spread between seeds."""
    spread = []
    for key, v in groups.items():
        bars = [b for _, b, _ in sorted(v)]
        ours = [x for _, _, x in sorted(v)]
        spread.append((max(bars) / min(bars), key, bars, ours))
    spread.sort(key=lambda r: -r[0])
    mid = sorted(r[0] for r in spread)
    median = (mid[(len(mid) - 1) // 2] + mid[len(mid) // 2]) / 2
    print(f"groups {len(spread)}: the bar's largest / smallest over seeds, median {median:.2f}")

    def gm_of(values):
        return math.exp(sum(map(math.log, values)) / len(values))

    over = [(key, gm_of(o), gm_of(b)) for _, key, b, o in spread if gm_of(o) > 1.1 * gm_of(b)]
    print(f"groups whose geometric mean over seeds is worse than the bar's by > 10 %: {len(over)}")
    for (mesh, object_, rig, truth), o, b in over:
        print(f"  {mesh} of {object_}, {rig}, {truth}: ours {o:.3f}, bar {b:.3f}")
    print("bar's largest / smallest over seeds (mesh of materials, rig, true material: bar, ours by seed)")
    for s, (mesh, object_, rig, truth), bars, ours in spread[:rows]:
        b = " ".join(f"{x:.3f}" for x in bars)
        o = " ".join(f"{x:.3f}" for x in ours)
        print(f"  {s:.2f}  {mesh} of {object_}, {rig}, {truth}: bar {b}; ours {o}")


if __name__ == "__main__":
    main()
