"""Which held-out error chooses the ladder's rung best, on a stored accuracy grid.

Usage: python3 scripts/heldout_study.py GRID/accuracy.json
       (docs/eval/heldout-study/accuracy.json: the grid run with the study build)

Each rung of a stored ladder carries its fold errors in several spaces (`fold_errors`: linear
pixels; `fold_errors_log`; `fold_errors_patch` since session 16: linear errors of sums over
patches of a twelfth of the image extent; and, where the grid was run with the study build,
commit d84e229 on branch `study-heldout`, `fold_errors_block` / `fold_errors_block_wide`: sums
over blocks of extent/32 and extent/12 pixels (the latter is today's patch), and
`fold_errors_clamp`: linear with each rendered pixel clamped to the brightest training pixel). For each space alone (simplest rung within one paired standard error of the best) and for
each pair (the `pareto` rule of `ladder::choose_by`: where the two choices differ, the richer
unless it is worse in the space that chose the simpler), the rendered environment error the
choice gets, against the better of the Lambert and Lambert + GGX baselines.

An estimate, as scripts/rechoose_ladder.py: a rung of another k is scored by the family's fit at
the chosen k, the hybrid is considered only where it was scored, and the trials' disagreement
guard only where the stored reason names it.
"""
import json, math, sys

d = json.load(open(sys.argv[1]))
SPACES = ['fold_errors', 'fold_errors_log', 'fold_errors_patch', 'fold_errors_block',
          'fold_errors_block_wide', 'fold_errors_clamp']


def folds(r, sp):
    return r.get(sp) or []


def mean(r, sp):
    f = folds(r, sp)
    if not f or any(x is None for x in f):
        return None
    return sum(f) / len(f)


def within(c, b, sp):
    fc, fb = folds(c, sp), folds(b, sp)
    if not fc or len(fc) != len(fb) or any(x is None for x in fc + fb):
        return False
    dd = [x - y for x, y in zip(fc, fb)]
    n = len(dd)
    m = sum(dd) / n
    sd = math.sqrt(sum((x - m) ** 2 for x in dd) / (n - 1)) if n > 1 else 0.0
    return m <= sd / math.sqrt(n)


def key(r):
    return (r['parameters'], -(r['eta'] or 0))


def choose(rungs, sp):
    ok = [(i, r) for i, r in enumerate(rungs) if mean(r, sp) is not None]
    if not ok:
        return None
    bi, b = min(ok, key=lambda t: mean(t[1], sp))
    cands = [(i, r) for i, r in ok if i == bi or within(r, b, sp)]
    return min(cands, key=lambda t: key(t[1]))[0]


def pareto(rungs, sa, sb):
    a, b = choose(rungs, sa), choose(rungs, sb)
    if a is None:
        return b
    if b is None or a == b:
        return a
    s_, r_, sp = (a, b, sa) if key(rungs[a]) <= key(rungs[b]) else (b, a, sb)
    inf = float('inf')
    er, es = mean(rungs[r_], sp), mean(rungs[s_], sp)
    return r_ if (er if er is not None else inf) <= (es if es is not None else inf) else s_


def rule_of(spaces):
    if len(spaces) == 1:
        return lambda rs: choose(rs, spaces[0])
    return lambda rs: pareto(rs, spaces[0], spaces[1])


def gm(v):
    return math.exp(sum(math.log(x) for x in v) / len(v))


rules = [[s] for s in SPACES] + [[a, 'fold_errors_log'] for a in SPACES if a != 'fold_errors_log']
print('| held-out error(s) | ratio gm | min | worse by > 10 % | losers |')
print('|---|---:|---:|---:|---|')
for spaces in rules:
    rule = rule_of(spaces)
    ratios, losers = [], []
    if not any(r.get(spaces[0]) for sc in d['scenes']
               for r in ((sc['variants'][0][1].get('Ok') or {}).get('ladder') or {}).get('rungs', [])):
        continue  # this grid did not store that space
    for sc in d['scenes']:
        ok = sc['variants'][0][1].get('Ok')
        if not ok or not ok.get('ladder'):
            continue
        base = min(sc['lambert']['environment'], sc['lambert_ggx']['environment'])
        lad = ok['ladder']
        rungs = [r for r in lad['rungs'] if r['family'] != 'hybrid']
        hyb = [r for r in lad['rungs'] if r['family'] == 'hybrid']
        alts = {f: e['environment'] for f, e in ok['alternatives']}
        alts[ok['model']['family']] = ok['chosen']['environment']
        c = rule(rungs)
        if c is None:
            continue
        fam = rungs[c]['family']
        if fam == 'basis' and hyb:
            h = hyb[0]
            if all(mean(h, s) is not None and mean(rungs[c], s) is not None
                   and mean(h, s) < mean(rungs[c], s) and not within(rungs[c], h, s)
                   for s in spaces):
                fam = 'hybrid'
        if fam in ('basis', 'hybrid') and 'disagree' in lad['reason'] + ok['model']['reason']:
            an = [r for r in rungs if r['family'] in ('lambert', 'lambert-ggx')]
            fam = an[rule(an)]['family']
        r = base / alts.get(fam, ok['chosen']['environment'])
        ratios.append(r)
        if r < 1 / 1.1:
            losers.append('%s/%s/%s/%s %.2f' % (sc['material'], sc['mesh'], sc['rig']['kind'],
                                                sc['seed'], r))
    if not ratios:
        continue
    print('| %s | %.3f | %.3f | %d | %s |' % (' + '.join(s.replace('fold_errors', 'linear').replace('linear_', '') for s in spaces),
                                         gm(ratios), min(ratios), len(losers), '; '.join(losers)))
