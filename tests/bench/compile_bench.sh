#!/usr/bin/env bash
# Compile throughput of `tgm-hmi compile` against LinuxCNC's `rs274 -g` on the same generated
# CAM-like program, both timed as whole processes (startup, reading, parsing, writing output).
#
#   tests/bench/compile_bench.sh [BUILD_DIR] [LINES]
#
# BUILD_DIR defaults to ./build, LINES to 1000000. Environment: RUNS (timed runs per tool,
# default 5), SEED (program seed, default 1), INCREMENTAL=1 (a G91 program instead of G90),
# WORK (scratch directory, default /tmp/tgm-compile-bench). Uses hyperfine when installed,
# otherwise the median of RUNS runs timed with date +%s%N. Results: BENCHMARKS.md "Compiler".
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
lines=${2:-1000000}
runs=${RUNS:-5}
seed=${SEED:-1}
work=${WORK:-/tmp/tgm-compile-bench}
gen=$build/tests/bench/gen/tgm_gen_cam_program
hmi=$build/client/tgm-hmi
config=$root/config/default.yaml

for exe in "$gen" "$hmi"; do
  if [[ ! -x $exe ]]; then
    echo "missing $exe; build first: cmake --build $build --target tgm-hmi tgm_gen_cam_program" >&2
    exit 2
  fi
done
rs274=$(command -v rs274 || true)
if [[ -z $rs274 ]]; then
  echo "rs274 not found on PATH (Debian package linuxcnc-uspace)" >&2
  exit 2
fi

mkdir -p "$work"
mode_flag=()
mode=G90
if [[ ${INCREMENTAL:-0} == 1 ]]; then
  mode_flag=(--incremental)
  mode=G91
fi
prog=$work/cam_${lines}_${mode}_seed${seed}.ngc
"$gen" --lines "$lines" --seed "$seed" "${mode_flag[@]}" -o "$prog"
nlines=$(wc -l < "$prog")
out=$work/out.tgmi

# Both must accept the program and see the same number of motions.
if ! "$hmi" compile "$prog" --config "$config" --out "$out" > "$work/tgm.log" 2>&1; then
  echo "tgm-hmi rejected $prog:" >&2
  head -20 "$work/tgm.log" >&2
  exit 1
fi
if ! "$rs274" -g "$prog" > "$work/rs274.out" 2> "$work/rs274.err"; then
  echo "rs274 rejected $prog:" >&2
  cat "$work/rs274.err" >&2
  exit 1
fi
ours=$("$hmi" compile "$prog" --config "$config" --dump text | grep -c -E '^ *[0-9]+  G[0-3] ' || true)
theirs=$(grep -c -E 'STRAIGHT_TRAVERSE|STRAIGHT_FEED|ARC_FEED' "$work/rs274.out" || true)
echo "program: $prog ($nlines lines, $mode, $(du -h "$prog" | cut -f1)); motions: tgm $ours, rs274 $theirs"
if [[ $ours != "$theirs" ]]; then
  echo "motion counts differ" >&2
  exit 1
fi

tgm_cmd="$hmi compile $prog --config $config --out $out"
rs_cmd="$rs274 -g $prog > /dev/null 2>&1"

median_of() { sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }

if command -v hyperfine > /dev/null; then
  json=$work/hyperfine.json
  hyperfine --style basic --warmup 1 --runs "$runs" --export-json "$json" \
    -n tgm-hmi "$tgm_cmd" -n rs274 "$rs_cmd"
  # hyperfine writes one "median" per command, in command order.
  mapfile -t med < <(grep -o '"median": *[0-9.e+-]*' "$json" | sed 's/.*: *//')
  t_tgm=${med[0]}
  t_rs=${med[1]}
  # Mean CPU time (user + system): steadier than wall time on a shared machine.
  mapfile -t usr < <(grep -o '"user": *[0-9.e+-]*' "$json" | sed 's/.*: *//')
  mapfile -t sys < <(grep -o '"system": *[0-9.e+-]*' "$json" | sed 's/.*: *//')
  cpu_note=$(awk -v a="${usr[0]}" -v b="${sys[0]}" -v c="${usr[1]}" -v d="${sys[1]}" \
    'BEGIN { printf "CPU time (user+system, mean): tgm-hmi %.4f s, rs274 %.4f s, ratio %.1f", a + b, c + d, (c + d) / (a + b) }')
  how="hyperfine, median of $runs runs after 1 warm-up"
else
  time_runs() {
    for _ in $(seq "$runs"); do
      local t0 t1
      t0=$(date +%s%N)
      bash -c "$1"
      t1=$(date +%s%N)
      echo "($t1 - $t0) / 1000000000" | bc -l
    done | median_of
  }
  bash -c "$tgm_cmd" && bash -c "$rs_cmd"  # warm-up
  t_tgm=$(time_runs "$tgm_cmd")
  t_rs=$(time_runs "$rs_cmd")
  how="date +%s%N, median of $runs runs after 1 warm-up"
fi

awk -v n="$nlines" -v a="$t_tgm" -v b="$t_rs" -v how="$how" 'BEGIN {
  printf "\n%-10s %12s %16s\n", "process", "median [s]", "lines/s"
  printf "%-10s %12.4f %16.0f\n", "tgm-hmi", a, n / a
  printf "%-10s %12.4f %16.0f\n", "rs274", b, n / b
  printf "ratio (rs274 time / tgm-hmi time): %.1f   (%s)\n", b / a, how
}'
if [[ -n ${cpu_note:-} ]]; then
  echo "$cpu_note"
fi
