"""How far the model ladder's choice is from the best it could choose, on a stored accuracy grid.

Usage: python3 scripts/ladder_ceiling.py docs/eval/both/accuracy.json

For each scene, the ratio (better of the Lambert and Lambert + GGX baselines' environment error)
/ (ours), under several choices among the ladder's rungs, each scored by that family's own fit
against the truth (`alternatives`, stored by `bench accuracy`; the chosen one by `chosen`):
- as run: what the ladder chose;
- oracle: the family closest to the truth (what no held-out test can know; the ceiling of any
  choice among today's rungs);
- linear / log: simplest within one standard error of the best in that held-out space;
- lowest linear / lowest log: the lowest held-out error, no preference for the simple.
An estimate, not a re-run: a re-chosen basis rung at another k is scored with the basis fit
at the originally chosen k.
"""
import json, math, sys


def within(c, b, lin):
    fc = c['fold_errors'] if lin else c['fold_errors_log']
    fb = b['fold_errors'] if lin else b['fold_errors_log']
    if not fc or any(x is None for x in fc + fb):
        return False
    dd = [x - y for x, y in zip(fc, fb)]
    n = len(dd)
    m = sum(dd) / n
    sd = math.sqrt(sum((x - m) ** 2 for x in dd) / (n - 1)) if n > 1 else 0.0
    return m <= sd / math.sqrt(n)


def err(r, lin):
    return r['error'] if lin else r['error_log']


def simplest_within(rungs, lin):
    ok = [r for r in rungs if err(r, lin) is not None]
    best = min(ok, key=lambda r: err(r, lin))
    cands = [r for r in ok if r is best or within(r, best, lin)]
    return min(cands, key=lambda r: (r['parameters'], -(r['eta'] or 0)))


def lowest(rungs, lin):
    return min((r for r in rungs if err(r, lin) is not None), key=lambda r: err(r, lin))


def gm(v):
    return math.exp(sum(math.log(x) for x in v) / len(v))


d = json.load(open(sys.argv[1]))
rules = {
    'as run': None,
    'oracle': None,
    'linear, simplest within 1 SE': lambda rs: simplest_within(rs, True),
    'log, simplest within 1 SE': lambda rs: simplest_within(rs, False),
    'lowest linear': lambda rs: lowest(rs, True),
    'lowest log': lambda rs: lowest(rs, False),
}
out = {k: [] for k in rules}
for sc in d['scenes']:
    ok = sc['variants'][0][1].get('Ok')
    if not ok or not ok.get('ladder'):
        continue
    base = min(sc['lambert']['environment'], sc['lambert_ggx']['environment'])
    env = {f: e['environment'] for f, e in ok['alternatives']}
    env[ok['model']['family']] = ok['chosen']['environment']
    rungs = ok['ladder']['rungs']
    for name, rule in rules.items():
        if name == 'as run':
            e = ok['chosen']['environment']
        elif name == 'oracle':
            e = min(env.values())
        else:
            e = env.get(rule(rungs)['family'], ok['chosen']['environment'])
        out[name].append(base / e)
print('| choice | scenes | ratio gm | min | worse by > 10 % |')
print('|---|---:|---:|---:|---:|')
for name, v in out.items():
    print('| %s | %d | %.3f | %.3f | %d |' % (name, len(v), gm(v), min(v), sum(x < 1 / 1.1 for x in v)))
