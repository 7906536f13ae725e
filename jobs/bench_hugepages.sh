#!/usr/bin/env bash
# Large allocations on 4 KiB pages against transparent huge pages (GLIBC_TUNABLES=
# glibc.malloc.hugetlb=1, which jobs/env.sh sets): whole `nimbus run`s of the default scene per
# model on NP ranks, the two settings alternating, `repeats` times each. Prints one markdown row
# per model: medians of the run's total and model-phase seconds and of the page faults of mpiexec
# and all it starts (perf stat, when perf is installed; else "-"), and total(on) / total(off).
#   bash jobs/bench_hugepages.sh [build dir] [repeats] [ranks]   (defaults: build 3 2)
#   MODELS="diffusion dom" limits the models (default: montecarlo diffusion dom lpm psf).
set -euo pipefail
cd "$(dirname "$0")/.."
source jobs/env.sh
source jobs/bench_args.sh
build=${1:-build}
reps=${2:-3}
np=${3:-2}
need_binary "$build/bin/nimbus" nimbus "$build"
need_count repeats "$reps"
need_count ranks "$np"
models=${MODELS:-montecarlo diffusion dom lpm psf}
for m in $models; do
  [[ "$m" =~ ^(single|diffusion|dom|lpm|psf|montecarlo)$ ]] || { echo "$bench_script: unknown model '$m'" >&2; exit 1; }
done
others=$(echo ":${GLIBC_TUNABLES:-}:" | tr ':' '\n' | grep -v '^glibc.malloc.hugetlb=' | paste -sd: - | sed 's/^:*//; s/:*$//')
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
perf_ok=0
command -v perf >/dev/null 2>&1 && perf stat -e page-faults true >/dev/null 2>&1 && perf_ok=1

# run <setting> <model>: prints "total model faults" of one run.
run() {
  local tunables=$others
  [ "$1" = on ] && tunables="${others:+$others:}glibc.malloc.hugetlb=1"
  local cmd=(mpiexec -n "$np" "$build/bin/nimbus" run --out "$out/run" --set "model.name=$2")
  local log="$out/log" faults="-" ok=1
  if [ $perf_ok = 1 ]; then
    GLIBC_TUNABLES=$tunables perf stat -x, -e page-faults -o "$out/perf" "${cmd[@]}" > "$log" 2>&1 || ok=0
    faults=$(awk -F, '/page-faults/ { print $1 }' "$out/perf")
  else
    GLIBC_TUNABLES=$tunables "${cmd[@]}" > "$log" 2>&1 || ok=0
  fi
  local total model
  total=$(awk '$3 == "total" && NF == 4 { print $4 }' "$log")
  model=$(awk '$3 == "model" && NF == 4 { print $4 }' "$log")
  if [ $ok = 0 ] || [ -z "$total" ] || [ -z "$model" ]; then
    echo "$bench_script: the $2 run ($1) failed or printed no timers; its log ends:" >&2
    tail -5 "$log" >&2
    exit 1
  fi
  echo "$total $model $faults"
}

echo "### default scene, $np rank(s), medians of $reps runs per setting (4 KiB pages = off, huge pages = on)"
echo
echo "| model | total s, off | total s, on | on / off | model phase s, off | model phase s, on | page faults, off | page faults, on |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- |"
for m in $models; do
  : > "$out/off"; : > "$out/on"
  for ((r = 0; r < reps; ++r)); do
    run off "$m" >> "$out/off"
    run on "$m" >> "$out/on"
  done
  col() { awk -v c="$2" '{ print $c }' "$out/$1" | median; }
  faults() { if [ $perf_ok = 1 ]; then col "$1" 3; else echo "-"; fi; }
  t_off=$(col off 1); t_on=$(col on 1)
  echo "| $m | $t_off | $t_on | $(ratio "$t_on" "$t_off") | $(col off 2) | $(col on 2) | $(faults off) | $(faults on) |"
done
