"""What the model ladder's "both metrics" choice (a richer rung must win beyond noise in linear
and in log held-out error, and a GGX peak only when it lowers both) would have chosen on a stored
accuracy grid, and the rendered error it would have got.

Usage: python3 scripts/rechoose_ladder.py docs/eval/refined/accuracy.json [--pareto]

With --median, a rung's score is the median over its folds instead of the mean (a study of a
held-out error robust to one bad fold; not in the code).
With --front, the `pareto` choice among the rungs that no other rung dominates beyond noise
(better by more than one standard error in one space, not worse by more than one in the other).
With --pareto, the `pareto` choice instead (`--held-out pareto`: the richer of the linear and
the log choice unless its mean error is worse in the space that chose the simpler one).

Reads each scene's ladder rungs (fold errors, both spaces) and each family's own fit against the
truth (`alternatives`, from `bench accuracy`). An estimate, not a re-run: a re-chosen basis rung
at another k is scored with the basis fit at the originally chosen k, and the trials'
disagreement guard is applied only where the stored reason names it.
"""
import json, math, sys
d = json.load(open([a for a in sys.argv[1:] if not a.startswith('--')][0]))
def within(c, b, lin):
    fc = c['fold_errors'] if lin else c['fold_errors_log']
    fb = b['fold_errors'] if lin else b['fold_errors_log']
    if any(x is None for x in fc+fb) or not fc: return False
    dd = [x-y for x,y in zip(fc,fb)]
    n=len(dd); m=sum(dd)/n
    sd = math.sqrt(sum((x-m)**2 for x in dd)/(n-1)) if n>1 else 0
    return m <= sd/math.sqrt(n)
def err(r, lin):
    if MEDIAN:
        f = [x for x in (r['fold_errors'] if lin else r['fold_errors_log']) if x is not None]
        return sorted(f)[len(f)//2] if len(f) % 2 else (sum(sorted(f)[len(f)//2-1:len(f)//2+1])/2 if f else None)
    return r['error'] if lin else r['error_log']
MEDIAN = '--median' in sys.argv
def key(r): return (r['parameters'], -(r['eta'] or 0))
def choose(rungs, lin):
    ok=[(i,r) for i,r in enumerate(rungs) if err(r,lin) is not None]
    if not ok: return None
    bi,b = min(ok, key=lambda t: err(t[1],lin))
    cands=[(i,r) for i,r in ok if i==bi or within(r,b,lin)]
    return min(cands, key=lambda t: key(t[1]))[0]
def both(rungs):
    a=choose(rungs,True); b=choose(rungs,False)
    if a is None: return b
    if b is None: return a
    return a if key(rungs[a])<=key(rungs[b]) else b
def pareto(rungs):
    # the richer of the two choices unless its mean error is worse in the space that chose
    # the simpler one (`--held-out pareto`)
    a=choose(rungs,True); b=choose(rungs,False)
    if a is None: return b
    if b is None: return a
    if a == b: return a
    s_, r_, lin = (a,b,True) if key(rungs[a])<=key(rungs[b]) else (b,a,False)
    inf=float('inf')
    er = err(rungs[r_],lin); es = err(rungs[s_],lin)
    return r_ if (er if er is not None else inf) <= (es if es is not None else inf) else s_
def beats(a, b, lin):
    # rung a's held-out error is lower than b's beyond one standard error of their paired
    # fold differences
    ea, eb = err(a, lin), err(b, lin)
    return ea is not None and eb is not None and ea < eb and not within(b, a, lin)
def dominated(rungs, i):
    # another rung is better beyond noise in one space and not worse beyond noise in the other
    b = rungs[i]
    for j, a in enumerate(rungs):
        if j == i: continue
        if (beats(a, b, True) and within(a, b, False)) or (beats(a, b, False) and within(a, b, True)):
            return True
    return False
def front(rungs):
    # the pareto choice among the rungs no other rung dominates beyond noise
    keep = [i for i in range(len(rungs)) if not dominated(rungs, i)]
    if not keep: return pareto(rungs)
    sub = [rungs[i] for i in keep]
    c = pareto(sub)
    return None if c is None else keep[c]
RULE = front if '--front' in sys.argv else (pareto if '--pareto' in sys.argv else both)
old_r=[]; new_r=[]; changed=0
rows=[]
for sc in d['scenes']:
    ok = sc['variants'][0][1].get('Ok')
    if not ok or not ok.get('ladder'): continue
    base = min(sc['lambert']['environment'], sc['lambert_ggx']['environment'])
    lad = ok['ladder']; rungs=[r for r in lad['rungs'] if r['family']!='hybrid']
    hyb=[r for r in lad['rungs'] if r['family']=='hybrid']
    alts = {f:e['environment'] for f,e in ok['alternatives']}
    oldfam = ok['model']['family']; oldenv = ok['chosen']['environment']
    alts[oldfam]=oldenv
    c = RULE(rungs); fam = rungs[c]['family']
    if fam=='basis' and hyb:
        h=hyb[0]; b=[r for r in rungs if r['family']=='basis' and r['k']==h['k'] and r['eta']==h['eta']]
        if b:
            b=b[0]
            better=lambda lin: err(h,lin) is not None and err(h,lin)<err(b,lin) and not within(b,h,lin)
            if better(True) and better(False): fam='hybrid'
    if fam in ('basis','hybrid') and 'disagree' in lad['reason'] + ok['model']['reason']:
        an=[r for r in rungs if r['family'] in ('lambert','lambert-ggx')]
        fam = an[RULE(an)]['family']
    newenv = alts.get(fam, oldenv)
    if fam!=oldfam: changed+=1
    old_r.append(base/oldenv); new_r.append(base/newenv)
    rows.append((sc['material'],sc['mesh'],sc['seed'],sc['rig'], oldfam, fam, round(base/oldenv,2), round(base/newenv,2)))
gm=lambda v: math.exp(sum(math.log(x) for x in v)/len(v))
for r in rows:
    if r[4]!=r[5]: print(r)
print('scenes',len(old_r),'changed',changed)
print('old gm %.3f min %.3f worse>10%% %d'%(gm(old_r),min(old_r),sum(x<1/1.1 for x in old_r)))
print('new gm %.3f min %.3f worse>10%% %d'%(gm(new_r),min(new_r),sum(x<1/1.1 for x in new_r)))
