# Sourced by the benchmark scripts (bench_defaults, bench_uncertainty, bench_scenes): the simulated drive of one
# preset, odometry and world, made once and reused.
#
#   data=$(simulate_once LABEL PRESET ODOMETRY WORLD SOURCE)
#
# Prints $out/data/PRESET_ODOMETRY_wWORLD, first simulating it with $scenecal when its rig.yaml is missing
# (--seed WORLD; ODOMETRY exact: --odometry-noise 0; DISTANCE set: --distance DISTANCE). SOURCE unknown removes
# rig.yaml's trajectory_source (the automatic method must then judge the drift itself); given keeps it. LABEL
# names the calling script in its messages. Exits 1 with the simulator's log when it fails.
simulate_once() {
  local label=$1 preset=$2 odometry=$3 world=$4 source_mode=$5
  local data="$out/data/${preset}_${odometry}_w${world}"
  if [[ ! -f "$data/rig.yaml" ]]; then
    local args=(simulate --preset "$preset" --seed "$world" --output "$data")
    if [[ $odometry == exact ]]; then args+=(--odometry-noise 0); fi
    if [[ -n ${DISTANCE:-} ]]; then args+=(--distance "$DISTANCE"); fi
    echo "$label: simulating $data" >&2
    "$scenecal" "${args[@]}" >"$data.simulate.log" 2>&1 || { cat "$data.simulate.log" >&2; exit 1; }
    if [[ $source_mode == unknown ]]; then
      grep -v '^trajectory_source:' "$data/rig.yaml" >"$data/rig.yaml.tmp" && mv "$data/rig.yaml.tmp" "$data/rig.yaml"
    fi
  fi
  echo "$data"
}
