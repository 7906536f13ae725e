#!/usr/bin/env bash
# PSF benchmark (issue 7): the light-volume pyramid at N³ (target < 1 s at 128³), and a W×H
# render of the default cumulus with the psf model against the single-scattering render of the
# same image (target within 3x), on 1 and 2 ranks (target 2-rank speed-up >= 1.6). Medians of
# `repeats` after a warm-up. Build first: cmake --build <build> --target bench_psf
#   bash jobs/bench_psf.sh [build dir] [N] [W] [H] [repeats]   (defaults: build 128 1920 1080 3)
set -euo pipefail
cd "$(dirname "$0")/.."
source jobs/env.sh
source jobs/bench_args.sh
build=${1:-build}
n=${2:-128}; w=${3:-1920}; h=${4:-1080}; reps=${5:-3}
need_binary "$build/bin/bench_psf" bench_psf "$build"
need_count N "$n"; need_count W "$w"; need_count H "$h"; need_count repeats "$reps"
echo "| grid | image | ranks | light terms | pyramid s | psf preprocess s | single render s | psf render s | psf / single |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
rows=()
for np in 1 2; do
  row=$(mpiexec -n "$np" "$build/bin/bench_psf" "$n" "$w" "$h" "$reps")
  echo "$row"
  rows+=("$row")
done
# 2-rank speed-up of the psf render and of pyramid + render.
"${NIMBUS_PYTHON}" - "${rows[@]}" <<'PY'
import sys
r = [[c.strip() for c in row.strip('|').split('|')] for row in sys.argv[1:]]
pyr1, pyr2 = float(r[0][4]), float(r[1][4])
ren1, ren2 = float(r[0][7]), float(r[1][7])
print(f"\n2-rank speed-up: psf render {ren1 / ren2:.2f}x, pyramid {pyr1 / pyr2:.2f}x")
PY
