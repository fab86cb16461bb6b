"""Where a written table's rendered error lies (docs/evaluation.md 1ag): each (theta_h, theta_d)
region of the table in turn is given the truth, and the table is scored again.

Usage:
  python3 scripts/region_oracle.py BRDF_RIG TRUTH TABLE OUT

- BRDF_RIG: the binary (e.g. target/release/brdf-rig);
- TRUTH: a neural MERL fit (`.f32`, e.g. ../shared/data/merl-nbrdf/blue-acrylic.f32) or a MERL
  `.binary`; a neural fit is tabulated once into OUT with `brdf-rig merl tabulate`;
- TABLE: the written `brdf.binary` of a `brdf-rig reconstruct` run;
- OUT: a work folder (the tabulated truth and the swapped tables are written there).

Prints the table's environment error (`brdf-rig merl compare TRUTH TABLE`, the headline of
docs/error-metrics.md), then, for every region of REGIONS, the error with that region's cells
(every phi_d, every channel) taken from the truth: a region whose swap lowers the error most
is where the render's error comes from. Then the cosine-weighted energy of the table in each
theta_h band by theta_d band, over the truth's (green channel): `f cos theta_i cos theta_o`
summed with each bin's solid angle (`4 cos theta_d dw_h dw_d`, MERL's sqrt(theta_h) spacing).

Neural MERL fits as truth are approximations of MERL, not measured MERL data.
Pure Python (no numpy): a MERL table is read with `array`; a few seconds per region.
"""
import array, math, os, subprocess, sys

N_TH, N_TD, N_PD = 90, 90, 180
SCALE = (1.0 / 1500, 1.15 / 1500, 1.66 / 1500)
# (theta_h from, to, theta_d from, to), degrees
REGIONS = [(0, 1, 0, 91), (1, 3, 0, 91), (3, 6, 0, 91), (6, 12, 0, 91), (12, 25, 0, 91),
           (25, 91, 0, 91), (0, 91, 0, 30), (0, 91, 30, 60), (0, 91, 60, 75), (0, 91, 75, 91),
           (0, 91, 60, 65), (0, 91, 65, 70), (0, 91, 70, 75), (0, 6, 60, 75), (6, 25, 60, 75),
           (25, 91, 60, 75)]
BANDS_H = [0, 1, 3, 6, 12, 25, 91]
BANDS_D = [0, 30, 60, 75, 91]


def read_merl(path):
    with open(path, 'rb') as f:
        dims = array.array('i')
        dims.fromfile(f, 3)
        if list(dims) != [N_TH, N_TD, N_PD]:
            sys.exit(f'{path}: dimensions {list(dims)}, expected {[N_TH, N_TD, N_PD]}')
        v = array.array('d')
        v.frombytes(f.read())
    if len(v) != 3 * N_TH * N_TD * N_PD:
        sys.exit(f'{path}: {len(v)} values, expected {3 * N_TH * N_TD * N_PD}')
    return v


def write_merl(path, v):
    with open(path, 'wb') as f:
        array.array('i', [N_TH, N_TD, N_PD]).tofile(f)
        v.tofile(f)


def theta_h_deg(i):
    return ((i + 0.5) / N_TH) ** 2 * 90.0


def theta_d_deg(j):
    return (j + 0.5) * 90.0 / N_TD


def swap(table, truth, th0, th1, td0, td1):
    out = array.array('d', table)
    for c in range(3):
        for i in range(N_TH):
            if not th0 <= theta_h_deg(i) < th1:
                continue
            for j in range(N_TD):
                if td0 <= theta_d_deg(j) < td1:
                    k = ((c * N_TH + i) * N_TD + j) * N_PD
                    out[k:k + N_PD] = truth[k:k + N_PD]
    return out


def environment(rig, truth, table):
    r = subprocess.run([rig, 'merl', 'compare', truth, table], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f'merl compare {table}: {r.stderr.strip()}')
    for line in r.stdout.splitlines():
        if line.startswith('environment (rel'):
            return float(line.split()[-1])
    sys.exit(f'merl compare {table}: no environment line in {r.stdout!r}')


def band_energy(v, c=1):
    """Cosine-weighted energy per (theta_h band, theta_d band), channel c."""
    dpd = math.pi / N_PD
    e = [[0.0] * (len(BANDS_D) - 1) for _ in range(len(BANDS_H) - 1)]
    for i in range(N_TH):
        u = (i + 0.5) / N_TH
        th = u * u * math.pi / 2
        dth = math.pi / 2 * 2 * u / N_TH
        bh = max(b for b in range(len(BANDS_H) - 1) if BANDS_H[b] <= math.degrees(th))
        for j in range(N_TD):
            td = (j + 0.5) / N_TD * math.pi / 2
            bd = max(b for b in range(len(BANDS_D) - 1) if BANDS_D[b] <= math.degrees(td))
            w0 = math.sin(th) * dth * math.sin(td) * (math.pi / 2 / N_TD) * dpd * 4 * math.cos(td) * 2
            base = ((c * N_TH + i) * N_TD + j) * N_PD
            for p in range(N_PD):
                pd = (p + 0.5) * dpd
                x, z = math.sin(td) * math.cos(pd), math.cos(td)
                ci = math.cos(th) * z - math.sin(th) * x
                co = math.cos(th) * z + math.sin(th) * x
                f = v[base + p]
                if ci > 0 and co > 0 and f > 0:
                    e[bh][bd] += f * SCALE[c] * w0 * ci * co
    return e


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    rig, truth, table, out = sys.argv[1:]
    os.makedirs(out, exist_ok=True)
    if truth.endswith('.f32'):
        t = os.path.join(out, os.path.basename(truth)[:-4] + '.binary')
        if not os.path.exists(t):
            subprocess.run([rig, 'merl', 'tabulate', truth, t], check=True)
        truth = t
    tv, ov = read_merl(truth), read_merl(table)
    print(f'{table}: environment error {environment(rig, truth, table):.4f}')
    tmp = os.path.join(out, 'swapped.binary')
    for r in REGIONS:
        write_merl(tmp, swap(ov, tv, *r))
        print('theta_h %2d-%2d, theta_d %2d-%2d from the truth: %.4f' % (r + (environment(rig, truth, tmp),)))
    et, eo = band_energy(tv), band_energy(ov)
    print('energy (green), table / truth; rows theta_h, columns theta_d ' +
          ' '.join('%d-%d' % (BANDS_D[b], BANDS_D[b + 1]) for b in range(len(BANDS_D) - 1)))
    for a in range(len(BANDS_H) - 1):
        print('  %2d-%2d ' % (BANDS_H[a], BANDS_H[a + 1]) +
              ' '.join('%6.2f' % (eo[a][b] / et[a][b] if et[a][b] > 0 else float('nan'))
                       for b in range(len(BANDS_D) - 1)))


if __name__ == '__main__':
    main()
