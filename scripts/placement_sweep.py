#!/usr/bin/env python3
"""Random sensor placements over the generated worlds: mean and lowest F1 per method.

Two seeded sets of `ground_filter_eval` built-in scenes (exact truth, nothing to download),
the same on every machine and Python 3.8 or later:

  sparse-high  120 placements: `lidar`, `lidar16`, `verge`, `offroad`, `trail`; 16/32/64 evenly
               spread beams 1.5-4 m up, the lowest beam -25 to -10 deg, the highest 2-16 deg,
               512-2,048 firings a turn (trucks, buses, masts; docs/voxel_method.md)
  general      205 placements: the same worlds 0.5-3.5 m up, slopes, kerbs, ramps, other beam
               layouts, mounts pitched or rolled up to 8 deg, range noise, grass roughness
  registered   80 placements of merged and tripod clouds and other viewpoints: `mls`, `mls_air`,
               `stations`, `slam` (2-12 positions, offsets of +-40 m in z, thinned), `tls` and
               `tls_far` (tripods 1.2-2.5 m, other fields of view), `rosette` (0.4-4 m, pitched),
               `garage` (ceilings 2.2-6 m); the table also counts the scans that
               `scan_type: auto` sent to the airborne mode

    python3 scripts/placement_sweep.py sparse-high              # voxel and normal (3-5 minutes)
    python3 scripts/placement_sweep.py general --methods voxel
    python3 scripts/placement_sweep.py registered
    python3 scripts/placement_sweep.py sparse-high --list       # the scene specs only
    python3 scripts/placement_sweep.py sparse-high --per-scan   # one line per placement
    PEER_BIN=DIR python3 scripts/placement_sweep.py sparse-high --peers patchworkpp,linefit

--peers NAME,... runs DIR/<name>_driver (scripts/peers/README.md; DIR as for sensor_sweep.py) on
the same scans, written as KITTI .bin files by `ground_filter_eval --write-scans`, with each
placement's true sensor height where it has one (`--set sensor_height=H`: Patchwork++ and linefit
assume a fixed one), and scores their labels with `--score-labels`. F1 are labels, so the same
on any CPU.
"""
import argparse
import os
import random
import subprocess
import sys
import tempfile

from sensor_sweep import peer_bin, run_json

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def sparse_high(rng, n):
    for _ in range(n):
        kind = rng.choice(['lidar16', 'lidar', 'verge', 'offroad', 'trail'])
        beams = rng.choice([16, 16, 32, 32, 64])
        height = round(rng.uniform(1.5, 4.0), 2)
        vmin = round(rng.uniform(-25, -10), 1)
        vmax = round(rng.uniform(2, 16), 1)
        steps = rng.choice([512, 1024, 1024, 1800, 2048])
        seed = rng.randint(1, 60)
        yield ('builtin:%s:%d:sensor_height=%s,beams=%d,vertical_min_deg=%s,vertical_max_deg=%s,'
               'uniform_beams=1,azimuth_steps=%d' % (kind, seed, height, beams, vmin, vmax, steps))


def general(rng, n):
    for _ in range(n):
        kind = rng.choice(['lidar', 'verge', 'offroad', 'trail', 'lidar16', 'lidar', 'verge'])
        f = [('sensor_height', round(rng.uniform(0.5, 3.5), 2)),
             ('slope_x', round(rng.uniform(-0.12, 0.12), 3)),
             ('slope_y', round(rng.uniform(-0.08, 0.08), 3))]
        if kind in ('lidar', 'verge'):
            f += [('curb_height', round(rng.uniform(0, 0.3), 2)),
                  ('ramp_height', round(rng.uniform(-3, 3.5), 1))]
        if rng.random() < 0.4:
            f += [('beams', rng.choice([16, 32, 40, 64, 128]))]
            lo, hi = rng.uniform(-30, -10), rng.uniform(0, 22)
            f += [('vertical_min_deg', round(lo, 1)), ('vertical_max_deg', round(hi, 1)),
                  ('uniform_beams', 1), ('azimuth_steps', rng.choice([512, 1024, 1800, 2048]))]
        if rng.random() < 0.25:
            f += [('mount_pitch_deg', round(rng.uniform(-8, 8), 1))]
        if rng.random() < 0.25:
            f += [('mount_roll_deg', round(rng.uniform(-8, 8), 1))]
        if rng.random() < 0.2:
            f += [('range_noise_sigma', round(rng.uniform(0, 0.05), 3))]
        if kind in ('offroad', 'trail', 'verge') and rng.random() < 0.5:
            f += [('grass_roughness', round(rng.uniform(0, 0.15), 3))]
        seed = rng.randint(1, 50)
        yield 'builtin:%s:%d:%s' % (kind, seed, ','.join('%s=%s' % kv for kv in f))


def registered(rng, n):
    layouts = ['street', 'verge', 'offroad', 'trail']
    for _ in range(n):
        kind = rng.choice(['mls', 'stations', 'slam', 'tls', 'rosette', 'garage', 'mls_air',
                           'tls_far'])
        f = []
        if kind in ('mls', 'stations', 'slam', 'mls_air'):
            f += [('layout', rng.choice(layouts)), ('positions', rng.randint(2, 12)),
                  ('position_step', round(rng.uniform(2, 15), 1))]
            if rng.random() < 0.4:
                f += [('world_offset_z', round(rng.uniform(-40, 40), 1))]
            if rng.random() < 0.3:
                f += [('position_keep', round(rng.uniform(0.2, 1), 2))]
        if kind in ('tls', 'tls_far'):
            f += [('layout', rng.choice(layouts)),
                  ('tripod_height', round(rng.uniform(1.2, 2.5), 2)),
                  ('tls_points', rng.choice([200000, 500000])),
                  ('tls_min_elevation_deg', round(rng.uniform(-80, -30), 1)),
                  ('tls_max_elevation_deg', round(rng.uniform(20, 80), 1))]
        if kind == 'rosette':
            f += [('layout', rng.choice(layouts + ['garage'])),
                  ('sensor_height', round(rng.uniform(0.4, 4), 2)),
                  ('rosette_pitch_deg', round(rng.uniform(-45, 10), 1))]
        if kind == 'garage':
            f += [('ceiling_height', round(rng.uniform(2.2, 6), 2)),
                  ('sensor_height', round(rng.uniform(0.4, 2.0), 2))]
        yield 'builtin:%s:%d:%s' % (kind, rng.randint(1, 40), ','.join('%s=%s' % kv for kv in f))


# Each set: (generator, [(random seed, placements), ...]).
SETS = {'sparse-high': (sparse_high, [(5, 60), (6, 60)]),
        'general': (general, [(1, 5), (11, 100), (12, 100)]),
        'registered': (registered, [(31, 40), (32, 40)])}


def specs(name):
    gen, parts = SETS[name]
    out = []
    for seed, n in parts:
        out += list(gen(random.Random(seed), n))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('set', choices=sorted(SETS))
    ap.add_argument('--methods', default='voxel,normal')
    ap.add_argument('--eval', default=os.path.join(ROOT, '.ws/devel/lib/ground_filter/'
                                                   'ground_filter_eval'))
    ap.add_argument('--peers', default='', help='driver names in $PEER_BIN (true heights)')
    ap.add_argument('--first', type=int, default=0, help='only the first N placements')
    ap.add_argument('--list', action='store_true', help='print the scene specs only')
    ap.add_argument('--per-scan', action='store_true', help='one line per placement')
    a = ap.parse_args()
    todo = specs(a.set)
    if a.first > 0:
        todo = todo[:a.first]
    if a.list:
        print('\n'.join(todo))
        return
    if not os.access(a.eval, os.X_OK):
        sys.exit('placement_sweep: no %s (build first, or --eval PATH)' % a.eval)
    peers = [x for x in a.peers.split(',') if x]
    for p in peers:
        if not os.access(os.path.join(peer_bin(), p + '_driver'), os.X_OK):
            sys.exit('placement_sweep: no %s/%s_driver (scripts/peers/README.md)' % (peer_bin(), p))
    table, types = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        # One eval call per method over every scene (a fresh filter per file); the first
        # also writes the scans the peers read.
        for m in [x for x in a.methods.split(',') if x]:
            write = ['--write-scans', tmp] if peers and not table else []
            files = run_json([a.eval, '--json', '--method', m] + write + todo)
            if not table:
                types = [f['scan_type'] for f in files]
                bins = [f.get('scan_file') for f in files]
            table[m] = [100.0 * f['f1'] for f in files]
        for p in peers:
            out = os.path.join(tmp, p)
            os.mkdir(out)
            driver = [os.path.join(peer_bin(), p + '_driver'), '--out', out]
            for s, b in zip(todo, bins):
                # the placement's own height where the scene names one (not tripods, maps)
                height = [w for w in s.split(':')[-1].split(',') if w.startswith('sensor_height=')]
                sets = ['--set', height[0]] if height else []
                subprocess.run(driver + sets + [b], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL, check=True)
            files = run_json([a.eval, '--json', '--score-labels', out] + todo)
            table[p + ' (true height)'] = [100.0 * f['f1'] for f in files]
    if a.per_scan:
        print('\t'.join(list(table)) + '\tscene')
        for i, s in enumerate(todo):
            print('\t'.join('%.2f' % table[k][i] for k in table) + '\t' + s)
    print('%s: %d placements; F1 %% per placement' % (a.set, len(todo)))
    print('| method | mean | lowest |\n|---|---|---|')
    for k, v in table.items():
        print('| %s | %.2f | %.2f |' % (k, sum(v) / len(v), min(v)))
    if types:
        print('scan_type auto: %s' % ', '.join('%d %s' % (types.count(t), t)
                                               for t in sorted(set(types))))


if __name__ == '__main__':
    main()
