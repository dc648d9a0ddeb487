#!/usr/bin/env python3
"""Fit speed and accuracy on real sets beside the simulator's demo (issue 50): `lightstage fit` on
the demo field (simulated, 256^2, 151 LEDs), the DiLiGenT objects in ../shared/data/diligent (as
shared, cropped to the object, and put back into their whole 612x512 frame) and the real RTI set
(.lp, imported). Per set, medians over --repeats runs of the fit's own figures: fitted pixels/s
(normals + fit, as `lightstage fit` prints it), where the time went (noise, normals, candidate
models, basis materials, shadows, writing), and the normals' mean angular error against the
set's ground truth where it has one (DiLiGenT's Normal_gt.mat; the demo's accuracy against its
ground truth is `lightstage bench fit`'s). Writes fit_real.csv and fit_real.png (pixels/s per set
against the demo's, and error against pixels/s) into --out.

    PYTHONPATH=build/python python3 scripts/bench_fit_real.py --out bench-out
"""
import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np
import scipy.io

import lightstage as ls
from diligent_normals import DATA, angular_error, crop_box, put_back_in_frame, read_codes

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..')
RTI = os.path.join(ROOT, '..', 'shared', 'data', 'rti')
PARTS = ('noise', 'normals', 'candidates', 'materials', 'shadows', 'writing')
ASKED_PER_S = {'real': 50e3, 'simulated': 100e3}  # Issue 50's figures, fitted pixels/s.


def demo_field(work, cli):
    """The demo's field (the simulated stage, its default scene), made by `lightstage demo`."""
    out = os.path.join(work, 'demo')
    subprocess.run([cli, 'demo', '--out', out, '--no-truth', '--quiet'], check=True,
                   stdout=subprocess.DEVNULL)
    return os.path.join(out, 'field.exr')


def sets(work, cli):
    """(name, kind, field EXR, (truth, mask, crop) or None) for every set measured."""
    yield 'demo 256x256', 'simulated', demo_field(work, cli), None
    for name in sorted(os.listdir(DATA)):
        folder = os.path.join(DATA, name)
        if not os.path.isfile(os.path.join(folder, 'Normal_gt.mat')):
            continue
        truth = scipy.io.loadmat(os.path.join(folder, 'Normal_gt.mat'))['Normal_gt']
        mask = read_codes(os.path.join(folder, 'mask.png'))
        mask = mask.reshape(mask.shape[0], mask.shape[1], -1)[..., 0] > 0
        whole = os.path.join(work, name + '_whole')
        put_back_in_frame(folder, whole)
        for frame, source, crop in (('cropped', folder, None),
                                    ('whole', whole, crop_box(folder))):
            field = os.path.join(work, f'{name}_{frame}.exr')
            ls.import_set(source, out=field)
            yield f'{name} ({frame})', 'real', field, (truth, mask, crop)
    for name in sorted(os.listdir(RTI)) if os.path.isdir(RTI) else []:
        folder = os.path.join(RTI, name)
        lp = [f for f in os.listdir(folder) if f.endswith('.lp')] if os.path.isdir(folder) else []
        if lp:
            field = os.path.join(work, name + '.exr')
            ls.import_set(os.path.join(folder, lp[0]), out=field)
            yield name, 'real', field, None


def measure(field, truth, repeats, work):
    runs = [ls.fit(field, out=os.path.join(work, 'maps.exr')) for _ in range(repeats)]
    summaries = [r.summary for r in runs]
    row = {'fitted': summaries[0]['fitted'],
           'seconds': round(statistics.median(s['seconds'] for s in summaries), 4)}
    row['fitted_per_s'] = round(statistics.median(s['fitted'] / s['seconds'] for s in summaries))
    for part in PARTS:
        row[part + '_s'] = round(statistics.median(s['times'][part] for s in summaries), 4)
    row['normal_error_deg'] = ''
    if truth is not None:
        normals, mask, crop = truth
        maps = runs[-1].maps
        normal = np.asarray(maps['normal'])
        if crop is not None:
            r0, r1, c0, c1 = crop
            normal = normal[r0:r1, c0:c1]
        row['normal_error_deg'] = round(angular_error({'normal': normal}, normals, mask), 3)
    return row


def chart(rows, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (speed, accuracy) = plt.subplots(1, 2, figsize=(13, 5))
    names = [r['set'] for r in rows]
    colours = ['tab:orange' if r['kind'] == 'simulated' else 'tab:blue' for r in rows]
    speed.barh(names, [r['fitted_per_s'] / 1e3 for r in rows], color=colours)
    for kind, asked in ASKED_PER_S.items():
        speed.axvline(asked / 1e3, ls='--', color='tab:orange' if kind == 'simulated' else
                      'tab:blue', label=f'asked, {kind}: {asked / 1e3:.0f}k')
    speed.invert_yaxis()
    speed.set_xlabel(f'fitted pixels/s (thousands; normals + fit, {os.cpu_count()} cores)')
    speed.set_title('lightstage fit: real sets against the simulated demo')
    speed.legend(loc='lower right')
    for r in rows:
        if r['normal_error_deg'] != '':
            accuracy.scatter(r['fitted_per_s'] / 1e3, r['normal_error_deg'], color='tab:blue')
            accuracy.annotate(r['set'], (r['fitted_per_s'] / 1e3, r['normal_error_deg']),
                              textcoords='offset points', xytext=(4, 4), fontsize=8)
    accuracy.set_yscale('log')
    accuracy.set_xlabel('fitted pixels/s (thousands)')
    accuracy.set_ylabel('mean angular error of the normals (degrees)')
    accuracy.set_title('accuracy against speed (ground-truth normals)')
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', default='bench-out')
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--cli', default=os.environ.get(
        'LIGHTSTAGE_CLI', os.path.join(ROOT, 'build', 'app', 'cli', 'lightstage')))
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix='fit_real_') as work:
        for name, kind, field, truth in sets(work, args.cli):
            row = {'set': name, 'kind': kind, **measure(field, truth, args.repeats, work)}
            rows.append(row)
            print(f"{name:22s} {row['fitted']:7d} px {row['seconds']:6.2f} s "
                  f"{row['fitted_per_s'] / 1e3:6.1f}k px/s  noise {row['noise_s']:.2f} s  "
                  f"normals {row['normals_s']:.2f}  candidates {row['candidates_s']:.2f}  "
                  f"materials {row['materials_s']:.2f}  writing {row['writing_s']:.2f}  "
                  f"error {row['normal_error_deg']}", flush=True)
    with open(os.path.join(args.out, 'fit_real.csv'), 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    chart(rows, os.path.join(args.out, 'fit_real.png'))
    print(f'wrote {args.out}/fit_real.csv and fit_real.png')


if __name__ == '__main__':
    sys.exit(main())
