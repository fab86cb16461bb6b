"""Could the held-out images say where the peak average helps? For two runs of the same scenes, one
with the released rule (the basis and the basis + GGX peak averaged only where the held-out images
call the two even) and one with the average wherever the basis is written (the study build of
docs/evaluation.md section 1ab), lists every scene whose written table changed: how far the basis
+ peak's held-out log error lies above the basis's, in standard errors of their fold-by-fold
difference (z; the released rule averages within about 1), and the rendered environment error
of both runs with the better analytic baseline's ratio to each (a change within 1 % counts
as neither). A z that separated the scenes the
average helps from those it hurts would be a rule; sorted by z, the two kinds interleave.

Usage: python3 scripts/peak_average_z.py BEFORE AFTER [BEFORE AFTER ...]
  BEFORE, AFTER: accuracy.json of `brdf-rig bench accuracy` or external.json of
  `brdf-rig bench external` (which keeps each job's ladder since session 38), the same scenes.
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import heldout_vs_render  # noqa: E402


def z_of(ladder):
    """The basis + peak's held-out log excess over the chosen basis rung, in standard errors."""
    if not ladder:
        return None
    rungs = ladder['rungs']
    chosen = rungs[ladder['chosen']]
    hybrid = [r for r in rungs if r['family'] == 'hybrid']
    if chosen['family'] != 'basis' or not hybrid:
        return None
    a, b = hybrid[-1]['fold_errors_log'], chosen['fold_errors_log']
    d = [x - y for x, y in zip(a or [], b or []) if x is not None and y is not None]
    if len(d) < 2:
        return None
    m = sum(d) / len(d)
    se = math.sqrt(sum((x - m) ** 2 for x in d) / (len(d) - 1) / len(d))
    return m / se if se > 0 else math.inf


def rows_of(path):
    """{scene name: (ladder, ours env, better baseline env)}, read as heldout_vs_render reads."""
    return {r['name']: (r['ladder'], r['ours'], min(r['lambert'], r['lambert_ggx']))
            for r in heldout_vs_render.read_rows(path)}


def main(paths):
    if len(paths) < 2 or len(paths) % 2:
        sys.exit(__doc__)
    rows = []
    for before, after in zip(paths[::2], paths[1::2]):
        b, a = rows_of(before), rows_of(after)
        for key, (ladder, ours, base) in b.items():
            if key not in a or abs(a[key][1] - ours) < 1e-9:
                continue
            rows.append((z_of(ladder), key, ours, a[key][1], base))
    rows.sort(key=lambda r: (r[0] is None, r[0] or 0.0))
    print('| z | scene | ours before | after | ratio before | after | |')
    print('|---|---|---|---|---|---|---|')
    for z, key, before, after, base in rows:
        verdict = ('within 1 %' if abs(after - before) <= 0.01 * before
                   else 'helped' if after < before else 'hurt')
        name = key
        zs = '-' if z is None else f'{z:.2f}'
        print(f'| {zs} | {name} | {before:.3f} | {after:.3f} | {base / before:.2f} | '
              f'{base / after:.2f} | {verdict} |')
    hurt = [r[0] for r in rows if r[3] > 1.01 * r[2] and r[0] is not None]
    helped = [r[0] for r in rows if r[3] < 0.99 * r[2] and r[0] is not None]
    if hurt and helped:
        print(f'\nz of the scenes hurt: {min(hurt):.2f}-{max(hurt):.2f}; helped: '
              f'{min(helped):.2f}-{max(helped):.2f} ({len(hurt)} hurt, {len(helped)} helped)')


if __name__ == '__main__':
    main(sys.argv[1:])
