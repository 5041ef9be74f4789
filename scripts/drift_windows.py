#!/usr/bin/env python3
"""How a trajectory drifts over swathe-long windows, against the exact one of the same drive.

    scripts/drift_windows.py EXACT_DATASET DRIFTING_DATASET [--window 30] [--every 20]

Both datasets' trajectory.csv must sample the same times (`scenecal simulate` with the same --seed, with and
without --odometry-noise 0). For windows starting every EVERY metres and WINDOW metres long, prints the
drifting trajectory's stretch along the travel (its scale error over the window, percent) and its rotation
error at the window's end (deg, about the base's axes), then the median stretch: the part of the drift that
the images cannot see (docs/findings.md, "The drive's scale is invisible to the images").
"""
import argparse
import csv
import math
import signal
import statistics
import sys


def rotation(qx, qy, qz, qw):
    return [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]


def load(dataset):
    path = f'{dataset}/trajectory.csv'
    try:
        with open(path) as f:
            rows = list(csv.DictReader(f))
        return [(int(r['timestamp_us']), [float(r[k]) for k in 'xyz'],
                 rotation(*(float(r[k]) for k in ('qx', 'qy', 'qz', 'qw')))) for r in rows]
    except (OSError, KeyError, ValueError) as error:
        sys.exit(f'drift_windows: {path}: {error}')


def transpose(a):
    return [[a[j][i] for j in range(3)] for i in range(3)]


def times(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def apply(a, v):
    return [sum(a[i][k] * v[k] for k in range(3)) for i in range(3)]


def relative(p0, p1):  # T0^-1 T1: translation in the base at p0, rotation
    r0t = transpose(p0[2])
    return apply(r0t, [p1[1][i] - p0[1][i] for i in range(3)]), times(r0t, p1[2])


def angles(r):  # rotation vector (rad) of a rotation matrix
    c = max(-1.0, min(1.0, (r[0][0] + r[1][1] + r[2][2] - 1) / 2))
    a = math.acos(c)
    if a < 1e-12:
        return [0.0, 0.0, 0.0]
    f = a / (2 * math.sin(a))
    return [f * (r[2][1] - r[1][2]), f * (r[0][2] - r[2][0]), f * (r[1][0] - r[0][1])]


def main():
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # piped into head: stop quietly
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('exact')
    parser.add_argument('drifting')
    parser.add_argument('--window', type=float, default=30.0, help='window length, metres (default 30)')
    parser.add_argument('--every', type=float, default=20.0, help='window spacing, metres (default 20)')
    args = parser.parse_args()
    exact, drifting = load(args.exact), load(args.drifting)
    if len(exact) != len(drifting) or any(e[0] != d[0] for e, d in zip(exact, drifting)):
        sys.exit('drift_windows: the two trajectories do not sample the same times')
    distance = [0.0]
    for i in range(1, len(exact)):
        distance.append(distance[-1] + math.dist(exact[i][1], exact[i - 1][1]))
    print('start_m\tstretch_percent\trotation_error_deg_x,y,z')
    stretches, start, i = [], 0.0, 0
    while True:
        while i < len(exact) and distance[i] < start:
            i += 1
        j = i
        while j < len(exact) and distance[j] - distance[i] < args.window:
            j += 1
        if j >= len(exact):
            break
        t_exact, r_exact = relative(exact[i], exact[j])
        t_drift, r_drift = relative(drifting[i], drifting[j])
        length = math.sqrt(sum(v * v for v in t_exact))
        stretch = sum((t_drift[k] - t_exact[k]) * t_exact[k] for k in range(3)) / (length * length)
        error = angles(times(transpose(r_exact), r_drift))
        stretches.append(stretch)
        print(f'{distance[i]:.0f}\t{100 * stretch:+.2f}\t' + ','.join(f'{math.degrees(e):+.3f}' for e in error))
        start += args.every
    if not stretches:
        sys.exit(f'drift_windows: the drive is shorter than one {args.window} m window')
    print(f'median stretch over {len(stretches)} windows of {args.window:.0f} m: '
          f'{100 * statistics.median(stretches):+.2f} %')


if __name__ == '__main__':
    main()
