"""Does the held-out images' verdict predict the rendered one? Per scene: how much lower the chosen
rung's held-out log error is than the better analytic rung's (Lambert or Lambert + GGX, the
ladder's own fits), against how much better ours renders than the better analytic baseline
(the environment error's ratio, above 1: ours better). Then what a rule "write the analytic
rung unless the chosen one wins the held-out images by at least G" would have given.

Usage: python3 scripts/heldout_vs_render.py FILE [FILE ...]
  FILE: an accuracy.json of `brdf-rig bench accuracy` or an external.json of
  `brdf-rig bench external` (since session 38 it stores each job's ladder); one line per file
  in the summary, every scene in the table with --scenes.

An estimate, not a re-run: a scene switched to the analytic rung is scored with that family's
baseline fit (`lambert` / `lambert_ggx` of the file: the same model fitted to the same pixels),
and the plausibility step (hedge, peak average) of the switched result is not modelled.
"""
import json
import math
import sys


def read_rows(path):
    """Every scene (job) of the file with a ladder: name, ours, lambert, lambert_ggx (the
    environment errors), ladder, unseen."""
    d = json.load(open(path))
    out = []
    if 'scenes' in d:  # bench accuracy
        for s in d['scenes']:
            v = s['variants'][0][1]
            if 'Ok' not in v:
                continue
            v = v['Ok']
            lad = v.get('ladder')
            if not lad:
                continue
            out.append(dict(
                name='%s %s %s %s' % (s['material'], s['mesh'], s['rig']['kind'], s['seed']),
                ours=v['chosen']['environment'],
                lambert=s['lambert']['environment'],
                lambert_ggx=s['lambert_ggx']['environment'],
                ladder=lad, unseen=v['confidence']['unseen_energy']))
    else:  # bench external
        for r in d['results']:
            if not r.get('ladder') or 'Ok' not in r['ours'] or not r.get('lambert'):
                continue
            out.append(dict(
                name='%s %s' % (r['scene'], r['seed']),
                ours=r['ours']['Ok']['environment'],
                lambert=r['lambert']['environment'],
                lambert_ggx=r['lambert_ggx']['environment'],
                ladder=r['ladder'], unseen=r.get('unseen_energy')))
    return out


def rows_of(path):
    """[`read_rows`] with the chosen rung's held-out gain over the better analytic rung."""
    scored = []
    for x in read_rows(path):
        rungs = x['ladder']['rungs']
        ch = rungs[x['ladder']['chosen']]
        an = [r for r in rungs if r['family'] in ('lambert', 'lambert-ggx')
              and r['error_log'] is not None]
        if not an or ch['error_log'] is None:
            # a run whose ladder scored no analytic rung (e.g. `--model basis`): no gain to read
            print('%s: %s left out, its ladder has no held-out analytic rung to compare with'
                  % (path, x['name']), file=sys.stderr)
            continue
        scored.append(x)
        best = min(an, key=lambda r: r['error_log'])
        x['family'] = ch['family']
        x['gain'] = (best['error_log'] - ch['error_log']) / best['error_log']
        dd = [b - c for b, c in zip(best['fold_errors_log'], ch['fold_errors_log'])]
        n = len(dd)
        m = sum(dd) / n
        sd = math.sqrt(sum((y - m) ** 2 for y in dd) / (n - 1)) if n > 1 else 0.0
        x['t'] = m / (sd / math.sqrt(n)) if sd > 0 else float('inf') if m > 0 else 0.0
        base = min(x['lambert'], x['lambert_ggx'])
        x['ratio'] = base / x['ours']
        switched = x['lambert'] if best['family'] == 'lambert' else x['lambert_ggx']
        x['ratio_analytic'] = base / switched
    return scored


def spearman(a, b):
    def ranks(v):
        o = sorted(range(len(v)), key=lambda i: v[i])
        r = [0.0] * len(v)
        for k, i in enumerate(o):
            r[i] = k
        return r
    ra, rb = ranks(a), ranks(b)
    n = len(a)
    ma, mb = sum(ra) / n, sum(rb) / n
    cov = sum((x - ma) * (y - mb) for x, y in zip(ra, rb))
    va = math.sqrt(sum((x - ma) ** 2 for x in ra))
    vb = math.sqrt(sum((y - mb) ** 2 for y in rb))
    return cov / (va * vb) if va > 0 and vb > 0 else float('nan')


def gm(v):
    return math.exp(sum(math.log(x) for x in v) / len(v))


def main():
    files = [a for a in sys.argv[1:] if not a.startswith('--')]
    if not files:
        sys.exit(__doc__)
    gs = [0.0, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4]
    print('| file | scenes | rank correlation of gain and ratio | '
          + ' | '.join('G = %.2f' % g for g in gs) + ' |')
    print('|---|---|---|' + '---|' * len(gs))
    for f in files:
        rows = rows_of(f)
        rc = spearman([x['gain'] for x in rows], [math.log(x['ratio']) for x in rows])
        cells = []
        for g in gs:
            rs = [x['ratio'] if x['family'] in ('lambert', 'lambert-ggx') or x['gain'] >= g
                  else x['ratio_analytic'] for x in rows]
            cells.append('%.3f (%d)' % (gm(rs), sum(1 for r in rs if r < 1 / 1.1)))
        print('| %s | %d | %.2f | %s |' % (f, len(rows), rc, ' | '.join(cells)))
        if '--scenes' in sys.argv:
            for x in sorted(rows, key=lambda x: x['ratio']):
                print('    %-50s %-12s gain %6.3f (t %5.1f) ratio %6.3f unseen %s' % (
                    x['name'], x['family'], x['gain'], x['t'], x['ratio'],
                    '-' if x['unseen'] is None else '%.3f' % x['unseen']))


if __name__ == '__main__':
    main()
