"""Which theta_d shape the grazing peak of a written table should take (docs/evaluation.md 1x).

Usage:
  python3 scripts/grazing_study.py BRDF_RIG SCENES ACCURACY_JSON OUT [SCENE ...]

- BRDF_RIG: the binary (e.g. a copy of target/release/brdf-rig);
- SCENES: the `--scratch` folder of a `bench accuracy` run (one folder per scene,
  `MESH-MATERIAL-RIG-SEED`, each with `job.toml`);
- ACCURACY_JSON: that run's accuracy.json (the baselines' environment errors);
- OUT: a work folder (tables and truths are written there, reused when present).

For each scene the job is reconstructed twice as the grid does (`--refine-normals`, 64
components, stride 1 2 2, the target excluded, `--seed 1 + SEED`): as chosen (`auto`) and
with `--model lambert-ggx`. Then the written table's cells with theta_h below TH degrees and
theta_d from D0 up are replaced, offline, by the table's value at theta_d D0 - 1 times the
Lambert + GGX table's ratio between the two cells, averaged geometrically with the table's own
value with weight W on the carried one (`reconstruct::grazing` does this in the pipeline with
D0 = 55, TH = 10), and each variant is scored with `brdf-rig merl compare` against the neural
fit (neural MERL fits as truth: approximations of MERL, not measured MERL data). Prints, per
rig, the geometric mean over scenes of (better baseline's environment error / variant's) and
the scenes worse than the better baseline by more than 10 %.

Pure Python (no numpy): a MERL table is read with `array`; about 20 s per scene on 2 cores.
"""
import array, json, math, os, subprocess, sys
from collections import defaultdict

# (D0, TH, W): W = 1 replaces the cells by the carried value.
VARIANTS = [(55, 10, 1.0), (50, 10, 1.0), (60, 10, 1.0), (55, 90, 1.0),
            (55, 10, 0.25), (55, 10, 0.5), (55, 10, 0.75), (50, 10, 0.5), (60, 10, 0.5)]
N_TH, N_TD, N_PD = 90, 90, 180


def read_merl(path):
    with open(path, 'rb') as f:
        dims = array.array('i')
        dims.fromfile(f, 3)
        assert list(dims) == [N_TH, N_TD, N_PD], f'{path}: dimensions {list(dims)}'
        v = array.array('d')
        v.frombytes(f.read())
    assert len(v) == 3 * N_TH * N_TD * N_PD, f'{path}: {len(v)} values'
    return v


def write_merl(path, v):
    with open(path, 'wb') as f:
        array.array('i', [N_TH, N_TD, N_PD]).tofile(f)
        v.tofile(f)


def idx(c, h, d, p):
    return ((c * N_TH + h) * N_TD + d) * N_PD + p


def carried(table, shape, d0, th_max, w):
    out = array.array('d', table)
    for h in range(N_TH):
        if ((h + 0.5) / N_TH) ** 2 * 90.0 >= th_max:
            break
        for c in range(3):
            for d in range(d0, N_TD):
                for p in range(N_PD):
                    i, r = idx(c, h, d, p), idx(c, h, d0 - 1, p)
                    m, mr, sr, sc = table[i], table[r], shape[r], shape[i]
                    if min(m, mr, sr, sc) > 0.0:
                        out[i] = m ** (1.0 - w) * (mr * sc / sr) ** w
    return out


def env_error(rig, truth, table):
    text = subprocess.run([rig, 'merl', 'compare', truth, table], check=True,
                          capture_output=True, text=True).stdout
    for line in text.splitlines():
        if line.startswith('environment (relative'):
            return float(line.split()[-1])
    raise RuntimeError(f'no environment error in: {text}')


def main():
    rig, scenes, grid, out = sys.argv[1:5]
    names = sys.argv[5:] or sorted(os.listdir(scenes))
    base = {}
    for s in json.load(open(grid))['scenes']:
        rig_tag = 'spread' if s['rig']['kind'] == 'spread' else 'one30'
        key = f"{s['mesh']}-{s['material']}-{rig_tag}-{s['seed']}"
        base[key] = min(s['lambert']['environment'], s['lambert_ggx']['environment'])
    nbrdf = os.path.join(os.path.dirname(__file__), '..', 'data', 'merl-nbrdf')
    ratios = defaultdict(list)
    for name in names:
        mesh, rest = name.split('-', 1)
        rest, seed = rest.rsplit('-', 1)
        material, rig_tag = rest.rsplit('-', 1)
        truth = os.path.join(out, f'{material}-truth.binary')
        if not os.path.exists(truth):
            subprocess.run([rig, 'merl', 'tabulate', os.path.join(nbrdf, f'{material}.f32'),
                            truth], check=True, capture_output=True)
        tables = {}
        for label, extra in [('auto', []), ('lg', ['--model', 'lambert-ggx'])]:
            d = os.path.join(out, name, label)
            if not os.path.exists(os.path.join(d, 'brdf.binary')):
                subprocess.run([rig, 'reconstruct', os.path.join(scenes, name, 'job.toml'),
                                '--out', d, '--refine-normals', '--basis-components', '64',
                                '--basis-stride', '1,2,2', '--exclude', material,
                                '--seed', str(1 + int(seed))] + extra,
                               check=True, capture_output=True)
            tables[label] = os.path.join(d, 'brdf.binary')
        auto, lg = read_merl(tables['auto']), read_merl(tables['lg'])
        scores = {'auto': env_error(rig, truth, tables['auto']),
                  'lg': env_error(rig, truth, tables['lg'])}
        tmp = os.path.join(out, name, 'variant.binary')
        for d0, th, w in VARIANTS:
            write_merl(tmp, carried(auto, lg, d0, th, w))
            scores[f'd0={d0} th<{th} w={w}'] = env_error(rig, truth, tmp)
        os.remove(tmp)
        print(name, ' '.join(f'{k}:{v:.4f}' for k, v in scores.items()), flush=True)
        for k, v in scores.items():
            ratios[(rig_tag, k)].append(base[name] / v)
    for (rig_tag, k), r in sorted(ratios.items()):
        gm = math.exp(sum(map(math.log, r)) / len(r))
        worse = sum(x < 1 / 1.1 for x in r)
        print(f'{rig_tag:7} {k:24} scenes {len(r):3} gm {gm:.3f} min {min(r):.2f} worse {worse}')


if __name__ == '__main__':
    main()
