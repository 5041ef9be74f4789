#!/usr/bin/env bash
# How wide the no-flag default's basin of convergence is: where starts far from the truth end, against where
# near starts end, on the same simulated drives.
#
#   scripts/bench_basin.sh [OUT_DIR]
#
# Runs scripts/bench_defaults.sh twice on the same data (PRESETS, default robotcar; ODOMETRY, default exact;
# WORLDS, default "1 2 3"; SETTINGS, default auto): near starts NEAR_T m / NEAR_R deg off (default 0.1, 3;
# NEAR_STARTS, default "1 2 3 4 5") and far starts FAR_T m / FAR_R deg off (default 0.3, 10; FAR_STARTS, default
# "1 2 3 4 5"), each in a random direction per seed. Per world and lidar, the reference end is the near starts'
# medoid (the near answer with the smallest summed distance to the others); a far start "reached the basin" when
# it ended within TOL_T m and TOL_R deg of it (default 0.005, 0.1). Prints a Markdown table (per world and lidar:
# far starts reached / run, the largest distance from the reference end, the near ends' spread, the errors against
# the truth) and keeps it in OUT_DIR/table.md. Other variables are bench_defaults.sh's (SCENECAL, THREADS,
# DISTANCE, SOURCE). TABLE_ONLY=1 prints the table again from the runs kept in OUT_DIR.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/bench_basin}
export PRESETS=${PRESETS:-robotcar} ODOMETRY=${ODOMETRY:-exact} WORLDS=${WORLDS:-"1 2 3"} SETTINGS=${SETTINGS:-auto}
near_t=${NEAR_T:-0.1} near_r=${NEAR_R:-3} far_t=${FAR_T:-0.3} far_r=${FAR_R:-10}
tol_t=${TOL_T:-0.005} tol_r=${TOL_R:-0.1}

if [[ ${TABLE_ONLY:-0} != 1 ]]; then
  mkdir -p "$out/near" "$out/far"
  # The far runs use the near runs' simulated drives.
  [[ -e "$out/far/data" ]] || ln -s ../near/data "$out/far/data"
  STARTS=${NEAR_STARTS:-"1 2 3 4 5"} PERTURB_T=$near_t PERTURB_R=$near_r scripts/bench_defaults.sh "$out/near" >/dev/null
  STARTS=${FAR_STARTS:-"1 2 3 4 5"} PERTURB_T=$far_t PERTURB_R=$far_r scripts/bench_defaults.sh "$out/far" >/dev/null
fi

python3 - "$out" "$tol_t" "$tol_r" "$near_t" "$near_r" "$far_t" "$far_r" <<'PY'
import csv, math, re, sys
out, tol_t, tol_r = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
near_t, near_r, far_t, far_r = sys.argv[4:8]

def rotation(roll, pitch, yaw):  # R = Rz(yaw) Ry(pitch) Rx(roll), FORMAT.md
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]

def distance(a, b):  # (metres, degrees) between two [x, y, z, roll, pitch, yaw]
    t = math.dist(a[:3], b[:3])
    ra, rb = rotation(*a[3:]), rotation(*b[3:])
    trace = sum(ra[i][k] * rb[i][k] for i in range(3) for k in range(3))  # trace(Ra^T Rb)
    return t, math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1) / 2))))

def answers(folder):  # (preset, odometry, world, setting, lidar) -> [(start, tuple, error t, error r)]
    found = {}
    for row in csv.DictReader(open(f'{out}/{folder}/results.tsv'), delimiter='\t', quoting=csv.QUOTE_NONE):
        tag = f"{row['preset']}_{row['odometry']}_w{row['world']}_{row['setting']}_{row['start']}"
        text = open(f'{out}/{folder}/runs/{tag}.yaml').read()
        block = text.split('\nlidars:\n', 1)[1].split('\npairs:', 1)[0]
        m = re.search(r'\n  ' + re.escape(row['lidar']) + r':\n    T_base_lidar: \[([^\]]*)\]', '\n' + block)
        if not m: sys.exit(f'bench_basin: no T_base_lidar of {row["lidar"]} in {tag}.yaml')
        key = (row['preset'], row['odometry'], row['world'], row['setting'], row['lidar'])
        found.setdefault(key, []).append((row['start'], [float(v) for v in m.group(1).split(',')],
                                          100 * float(row['translation_m']), float(row['rotation_deg'])))
    return found

near, far = answers('near'), answers('far')
lines = [f'| data | world | lidar | far starts ({far_t} m / {far_r} deg) within {100 * tol_t:g} cm / {tol_r:g} deg '
         f'of the near ends | largest distance from the near ends | spread of the near ends ({near_t} m / {near_r} deg) '
         '| error of the far ends: median / worst |',
         '|---|---|---|---|---|---|---|']
reached_all = run_all = 0
for key in sorted(near):
    if key not in far: continue
    preset, odometry, world, setting, lidar = key
    ends = [a[1] for a in near[key]]
    medoid = min(ends, key=lambda e: sum(sum(distance(e, o)) for o in ends))
    spread = [distance(medoid, e) for e in ends]
    gaps = [distance(medoid, a[1]) for a in far[key]]
    reached = sum(1 for t, r in gaps if t <= tol_t and r <= tol_r)
    reached_all += reached
    run_all += len(gaps)
    ft = sorted(a[2] for a in far[key])
    fr = sorted(a[3] for a in far[key])
    lines.append(f'| {preset}, {odometry} odometry, {setting} | {world} | {lidar} | {reached} of {len(gaps)} | '
                 f'{100 * max(g[0] for g in gaps):.2f} cm, {max(g[1] for g in gaps):.3f} deg | '
                 f'{100 * max(s[0] for s in spread):.2f} cm, {max(s[1] for s in spread):.3f} deg | '
                 f'{ft[len(ft) // 2]:.2f} / {ft[-1]:.2f} cm, {fr[len(fr) // 2]:.3f} / {fr[-1]:.3f} deg |')
table = '\n'.join(lines) + '\n'
table += f'\nIn all: {reached_all} of {run_all} far starts ({100 * reached_all / max(run_all, 1):.0f} %) reached the near ends.\n'
open(f'{out}/table.md', 'w').write(table)
print(table, end='')
PY
