#!/usr/bin/env bash
# Each bad input must: exit non-zero (mpiexec reports the worst rank), print exactly one
# "nimbus: error:" line naming the problem, and finish well before the timeout (no hang), with
# every rank leaving through the normal path (no "exiting improperly" from mpiexec) and no
# library's error dump (no "PETSC ERROR" lines).
# `nimbus info` must refuse what a run refuses before computing, with the same message.
set -u
nimbus=$1 mpiexec=$2 np=$3 scenes=$4
# On 1 rank, mpiexec's abort after a non-zero exit has no rank left to stop, yet Open MPI 4.1
# waits out its SIGTERM/SIGKILL sequence (odls_base_sigkill_timeout, 1 s, twice): `mpiexec -n 1
# false` takes 2.1 s, 0.11 s without the wait, and this script 167 s, 40 s without it (alone
# on this 2-core machine). Exit codes are unchanged. On 2 ranks the wait stays: it gives a rank
# that was still leaving the time to do so, or to say "exiting improperly", which the checks
# below look for.
if [ "$np" = 1 ]; then export OMPI_MCA_odls_base_sigkill_timeout=0; fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0

expect_error() {  # expect_error "<grep pattern>" args...   (SUB=info: nimbus info, without --out)
  local pattern=$1; shift
  local out sub=${SUB:-run}
  if [ "$sub" = run ]; then set -- "$@" --out "$tmp/out"; fi
  out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" "$sub" "$@" 2>&1)
  local code=$?
  local lines
  lines=$(echo "$out" | grep -c "nimbus: error:")
  if [ $code -ne 0 ] && [ $code -ne 124 ] && [ "$lines" -eq 1 ] && echo "$out" | grep -q -- "$pattern" &&
     ! echo "$out" | grep -q "PETSC ERROR\|improperly"; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1))
    echo "FAIL (exit $code, $lines error lines, want /$pattern/): nimbus $sub $*"
    echo "$out" | tail -5
  fi
}

printf '[grid\nn = [4, 4, 4]\n' > "$tmp/malformed.toml"
printf '[grid]\nn = [4, 4, 4]\n[medium]\ndensty = 1.0\n' > "$tmp/misspelled.toml"
optics='[[optics]]\nname = "gray"\nsigma_t = 1.0\nalbedo = 0.9\ng = 0.5\n[sun]\nirradiance = 1.0\n[sky]\nradiance = 0.1\n[background]\ncolor = 0.1\n[render]\nemission_color = 1.0\n'
printf "[grid]\nn = [8, 8, 8]\n[medium]\nkind = \"raw\"\nfile = \"d.raw\"\n$optics" > "$tmp/raw.toml"
head -c 100 /dev/zero > "$tmp/d.raw"
printf "[grid]\nn = [8, 8, 8]\n[medium]\nkind = \"raw\"\nfile = \"missing.raw\"\n$optics" > "$tmp/missing.toml"
/usr/bin/python3 - "$tmp/nan.raw" <<'PY'
import struct, sys
v = [0.5] * 512; v[77] = float("nan")
open(sys.argv[1], "wb").write(struct.pack("<512f", *v))
PY
printf "[grid]\nn = [8, 8, 8]\n[medium]\nkind = \"raw\"\nfile = \"nan.raw\"\n$optics" > "$tmp/nan.toml"
/usr/bin/python3 - "$tmp/neg.raw" <<'PY'
import struct, sys
v = [0.5] * 512; v[300] = -1.0
open(sys.argv[1], "wb").write(struct.pack("<512f", *v))
PY
printf "[grid]\nn = [8, 8, 8]\n[medium]\nkind = \"raw\"\nfile = \"neg.raw\"\n$optics" > "$tmp/neg.toml"
small=(--set "grid.n=[12,12,8]" --set "camera.resolution=[16,12]")
# A volume source over cells without density (a sphere of radius 0.3 in an 8^3 grid of 1 m
# cells leaves the corner cell [0, 1)^3 empty).
printf "[grid]\nn = [8, 8, 8]\n[medium]\nkind = \"sphere\"\nsphere_radius = 0.3\n$optics[model]\nname = \"dom\"\n[[sources]]\nlo = [0, 0, 0]\nhi = [1, 1, 1]\n" > "$tmp/dark_source.toml"

expect_error "malformed" "$tmp/malformed.toml"
expect_error "densty" "$tmp/misspelled.toml"
expect_error "render.stepp: unknown key; did you mean 'step'" "${small[@]}" --set "render.stepp=0.5"
expect_error "albedo" "${small[@]}" --set "optics[0].albedo=1.5"
expect_error 'optics\[1\].g: .*g = 1 must satisfy |g| < 1' "${small[@]}" --set "optics[1].g=1.0"
expect_error "zero-size" --set "grid.n=[0,8,8]"
expect_error "looks at nothing" "${small[@]}" --set "camera.look_at=[0.5,-1.3,0.42]"
# J = C kappa beyond float32 in the view volume (it used to give a NaN image and exit 0).
expect_error "view source J = 5e+38 W/(m³ sr) of band gray at cell (3, 3, 3) is beyond float32" \
  "$scenes/dense_cube.toml" --set "grid.n=[12,12,12]" --set "camera.resolution=[16,12]" --set model.name=diffusion \
  --set render.mode=emission_absorption --set render.emission_color=3e38 --set medium.density=2
expect_error "has 100 bytes but the grid needs 2048" "$tmp/raw.toml"
expect_error "missing.raw" "$tmp/missing.toml"
expect_error "sources\[0\] covers no cell with density" "$tmp/dark_source.toml"
expect_error "density at cell (5, 1, 1) is nan" "$tmp/nan.toml"
expect_error "density at cell (4, 5, 4) is -1" "$tmp/neg.toml"
expect_error 'model.name = "nonsense" is not allowed' "${small[@]}" --set "model.name=\"nonsense\""
expect_error "looks at nothing" "${small[@]}" --set "camera.look_at=[0.5,-3.0,0.42]"
expect_error "camera.position is under the ground" "${small[@]}" --set 'background.kind="ground"' \
    --set "camera.position=[0.5,-1.3,-0.2]"
# Band names name the HDF5 datasets: refused at load time, not after the solve.
expect_error 'optics\[1\].name = "r" repeats optics\[0\].name' "${small[@]}" --set 'optics[1].name="r"'
expect_error 'optics\[0\].name = "a/b" is not a valid band name' "${small[@]}" --set 'optics[0].name="a/b"'
expect_error 'model.name = "auto" is not allowed' "${small[@]}" --set 'model.name="auto"'
# A grid far beyond any machine: refused before anything is allocated, on every rank.
expect_error "the grid does not fit in memory" --set "grid.n=[65536,65536,65536]"
# When the image is what does not fit, the message says so (it blamed the grid, and more ranks
# made it worse: a QA finding). 2 ranks of a 16384² image need about 30 GiB on the node, more
# than this machine type has (24 GiB); a larger machine skips the check.
avail_gib=$(awk '/MemAvailable/ {printf "%d", $2 / 1048576}' /proc/meminfo)
if [ "$np" = 2 ] && [ "$avail_gib" -lt 28 ]; then
  SUB=info expect_error "the run does not fit in memory.*the image (16384x16384 pixels, camera.resolution).*smaller camera.resolution" \
    --set "grid.n=[8,8,8]" --set "camera.resolution=[16384,16384]" --set 'model.name="single"'
fi
SUB=info
expect_error "camera.look_at: the camera looks at nothing" "${small[@]}" --set "camera.look_at=[0.5,-3.0,0.42]"
expect_error 'optics\[1\].name = "r" repeats' "${small[@]}" --set 'optics[1].name="r"'
expect_error "the grid does not fit in memory" --set "grid.n=[65536,65536,65536]"
# When the image is what does not fit, the message says so (it blamed the grid, and more ranks
# made it worse: a QA finding). 2 ranks of a 16384² image need about 30 GiB on the node, more
# than this machine type has (24 GiB); a larger machine skips the check.
avail_gib=$(awk '/MemAvailable/ {printf "%d", $2 / 1048576}' /proc/meminfo)
if [ "$np" = 2 ] && [ "$avail_gib" -lt 28 ]; then
  SUB=info expect_error "the run does not fit in memory.*the image (16384x16384 pixels, camera.resolution).*smaller camera.resolution" \
    --set "grid.n=[8,8,8]" --set "camera.resolution=[16384,16384]" --set 'model.name="single"'
fi
# Refusals that need the density (model checks before the light pass): info says them too.
expect_error "sources\[0\] covers no cell with density" "$tmp/dark_source.toml"
expect_error "exceeds model.montecarlo.max_replicated_memory_gb" "${small[@]}" --set "model.montecarlo.max_replicated_memory_gb=0.000001"
# More photons than a time budget can split (it ran for hours past a 3 s budget at 9e18).
SUB=info expect_error 'model.montecarlo.photons = 900000000000000 must be in \[1, 1e+14\]' "${small[@]}" \
  --set 'model.name="montecarlo"' --set "model.montecarlo.photons=900000000000000" --set "model.montecarlo.time_budget=3"
expect_error "with iteration = 'dsa' diverges on cells this thick" "${small[@]}" --set 'model.name="dom"' --set 'model.dom.scheme="diamond"' --set "optics[0].sigma_t=1.0"
unset SUB
# model.diffusion.petsc_options: one line naming the option, with PETSc's message and without
# its traceback; info refuses what PETSc rejects when it reads the options, as run does. (PETSc's
# own error handler made every rank but rank 0 sleep 10 s and exit without MPI_Finalize.)
petsc=("${small[@]}" --set 'model.name="diffusion"' --set 'model.diffusion.solver="petsc"' --set output.image=false)
rejected="model.diffusion.petsc_options: PETSc rejected '-diffusion_pc_type nonexistent': Unable to find requested PC type nonexistent"
expect_error "$rejected" "${petsc[@]}" --set "model.diffusion.petsc_options=-diffusion_pc_type nonexistent"
SUB=info expect_error "$rejected" "${petsc[@]}" --set "model.diffusion.petsc_options=-diffusion_pc_type nonexistent"
SUB=info expect_error "PETSc rejected '-diffusion_ksp_divtol abc': Input string abc has no numeric value" "${petsc[@]}" \
  --set "model.diffusion.petsc_options=-diffusion_ksp_type cg -diffusion_ksp_divtol abc -diffusion_pc_type jacobi"
SUB=info expect_error "'-pc_type' lacks the prefix of the solver's options, -diffusion_" "${petsc[@]}" --set "model.diffusion.petsc_options=-pc_type jacobi"
SUB=info expect_error "PETSc would ignore 'diffusion_pc_type'" "${petsc[@]}" --set "model.diffusion.petsc_options=diffusion_pc_type jacobi"
# Well formed, but no PETSc object reads it: refused by name after the first solve.
expect_error "PETSc did not use '-diffusion_pc_typo jacobi'" "${petsc[@]}" --set "model.diffusion.petsc_options=-diffusion_pc_typo jacobi"
# What only KSPSetUp finds out: one line too (PCMG cannot coarsen 12 cells: 11 is odd).
expect_error "KSPSetUp (model.diffusion.petsc_options = .*) failed with PETSc error 75: Ratio between levels" "${petsc[@]}" \
  --set "model.diffusion.petsc_options=-diffusion_pc_type mg -diffusion_pc_mg_levels 3 -diffusion_pc_mg_galerkin both"
# Unwritable output folder: a path below a regular file.
out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" run "${small[@]}" --out /proc/version/x 2>&1); code=$?
if [ $code -ne 0 ] && [ $code -ne 124 ] && echo "$out" | grep -q "nimbus: error: output folder '/proc/version/x' cannot be created: '/proc/version' is a file"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: unwritable output folder (exit $code)"; echo "$out" | tail -3; fi
# An output that would replace the run's own density file (it used to, silently): refused, the
# file untouched.
mkdir -p "$tmp/ow"
/usr/bin/python3 -c "import struct; open('$tmp/ow/nimbus.h5', 'wb').write(struct.pack('<1152f', *([0.5] * 1152)))"
cp "$tmp/ow/nimbus.h5" "$tmp/ow_copy"
out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" run "${small[@]}" --set 'medium.kind="raw"' \
  --set "medium.file=\"$tmp/ow/nimbus.h5\"" --out "$tmp/ow" 2>&1); code=$?
if [ $code -ne 0 ] && [ $code -ne 124 ] && echo "$out" | grep -q "nimbus: error: output '.*nimbus.h5' would overwrite the density file medium.file" &&
   cmp -s "$tmp/ow/nimbus.h5" "$tmp/ow_copy"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: output over medium.file (exit $code)"; echo "$out" | tail -3; fi
# An output path Open MPI's MPI-IO would abort on (a buffer overflow at ~245 characters): refused
# before any folder is made.
long=$(printf 'd%.0s' $(seq 1 120))
out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" run "${small[@]}" --out "$tmp/long/$long/$long" 2>&1); code=$?
if [ $code -ne 0 ] && [ $code -ne 124 ] && echo "$out" | grep -q "nimbus: error: output path '.*' is [0-9]* characters long, more than the 200" &&
   [ ! -e "$tmp/long" ]; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: long output path (exit $code)"; echo "$out" | tail -3; fi
SUB=info expect_error "output path '.*' is [0-9]* characters long, more than the 200" "${small[@]}" \
  --set "output.dir=\"$tmp/long/$long\"" --set "output.name=\"$long\""
SUB=info expect_error 'output.dir must not be empty: use "." for the working folder' "${small[@]}" --set 'output.dir=""'
# A density file whose path MPI-IO would abort on: refused by name, in run and in info, and the
# run leaves no output folder (it aborted with exit 134 and left the folder).
mkdir -p "$tmp/long_in/$long/$long"
/usr/bin/python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes(4 * 512))" "$tmp/long_in/$long/$long/d.raw"
expect_error "the density file's path is [0-9]* characters long, more than the 230 nimbus can open" \
  "$tmp/raw.toml" --set "medium.file=\"$tmp/long_in/$long/$long/d.raw\""
[ ! -e "$tmp/out" ] && pass=$((pass + 1)) || { fail=$((fail + 1)); echo "FAIL: long density path left $tmp/out"; }
SUB=info expect_error "the density file's path is [0-9]* characters long" \
  "$tmp/raw.toml" --set "medium.file=\"$tmp/long_in/$long/$long/d.raw\""
# model psf's light volumes (64 at most): info says it, before any run.
SUB=info expect_error "model psf: 65 light terms need 65 light volumes, more than the 64 supported; lower sky.directions" \
  "${small[@]}" --set 'model.name="psf"' --set "sky.directions=64"
# More ranks than z cells.
if [ "$np" -gt 1 ]; then expect_error "no cells" --set "grid.n=[8,8,1]"; fi
# The PETSc cross-check path needs slabs along z: the message names the keys.
if [ "$np" -gt 1 ]; then
  expect_error 'model.diffusion.solver = "petsc" needs slabs along z (grid.process_grid = \[1, 1, P\])' "${small[@]}" \
    --set 'model.name="diffusion"' --set 'model.diffusion.solver="petsc"' --set "grid.process_grid=[2,1,1]"
fi
# hypre's SMG needs a power-of-two period (it gave NaN on 24 cells periodic in x); run and info refuse.
expect_error 'model.diffusion.solver = "smg-pcg" needs a power-of-two number of cells on a periodic axis.*grid.n\[0\] = 12' \
  "${small[@]}" --set 'model.name="diffusion"' --set 'model.diffusion.solver="smg-pcg"' --set 'grid.periodic=[true,false,false]'
SUB=info expect_error 'model.diffusion.solver = "smg" needs a power-of-two number of cells' \
  "${small[@]}" --set 'model.name="diffusion"' --set 'model.diffusion.solver="smg"' --set 'grid.periodic=[false,true,false]'
# info --ranks checks the process grid of the planned run as that run does (no mpiexec needed).
SUB=info expect_error 'model.diffusion.solver = "petsc" needs slabs along z' "${small[@]}" --ranks 2 \
  --set 'model.name="diffusion"' --set 'model.diffusion.solver="petsc"' --set "grid.process_grid=[2,1,1]"
SUB=info expect_error 'model dom: grid.periodic axis x must not be split over ranks' "${small[@]}" --ranks 2 \
  --set 'model.name="dom"' --set 'grid.periodic=[true,false,false]' --set "grid.process_grid=[2,1,1]" --set 'light.method="exact"'
SUB=info expect_error 'light.method = "sweep" sweeps along z and needs slabs along z' "${small[@]}" --ranks 2 \
  --set 'light.method="sweep"' --set "grid.process_grid=[1,2,1]"
# ... and on a grid too big to describe on this one process, the limits that need no density
# (Monte Carlo's replicated grid: it used to pass there while smaller grids were refused).
# (--ranks plans from one process only.)
if [ "$np" -eq 1 ]; then
  SUB=info expect_error "Monte Carlo replicates the 2048x2048x1024 grid on every rank" "${small[@]}" --ranks 64 \
    --set 'model.name="montecarlo"' --set "grid.n=[2048,2048,1024]"
fi
# psf's own pass needs slabs along z; the message names psf, not the (exact) light pass.
if [ "$np" -gt 1 ] && "$nimbus" info --set "grid.n=[8,8,8]" 2>&1 | grep -q "models in this build:.*psf"; then
  expect_error "model psf needs slabs along z" "${small[@]}" --set 'model.name="psf"' --set "grid.process_grid=[2,1,1]"
  # ... each at least 3 layers thick (its light volume's ghosts come from the adjacent rank):
  # refused by info as by run, before the light pass (5 layers on 2 ranks crashed MPI before).
  SUB=info expect_error "model psf needs at least 3 z layers per rank" --set "grid.n=[8,8,5]" --set 'model.name="psf"'
  expect_error "model psf needs at least 3 z layers per rank" --set "grid.n=[8,8,5]" --set 'model.name="psf"' --set output.image=false
  # Too few layers for even 2 ranks: the advice is 1 rank (it said "at most 0 ranks").
  if [ "$np" -eq 2 ]; then
    expect_error "2 layers on 2 ranks leave 1; use at most 1 rank\$" --set "grid.n=[8,8,2]" --set 'model.name="psf"' --set output.image=false
  fi
fi
# Decompositions the light pass or a model cannot use: info refuses them as run does, before
# the light pass.
if [ "$np" -gt 1 ]; then
  SUB=info expect_error 'light.method = "sweep" sweeps along z and needs slabs' "${small[@]}" --set 'light.method="sweep"' --set "grid.process_grid=[$np,1,1]"
  expect_error 'light.method = "sweep" sweeps along z and needs slabs' "${small[@]}" --set 'light.method="sweep"' --set "grid.process_grid=[$np,1,1]"
fi
SUB=info expect_error "model dom: grid.periodic z is not supported" "${small[@]}" --set 'model.name="dom"' --set "grid.periodic=[false,false,true]"
# Periodic z with a sun: light leaving the bottom would re-enter at the top (no light pass models it).
SUB=info expect_error "is not horizontal .* and grid.periodic z is set" "${small[@]}" --set "grid.periodic=[false,false,true]"
expect_error "is not horizontal .* and grid.periodic z is set" "${small[@]}" --set 'model.name="single"' --set "grid.periodic=[false,false,true]" --set 'light.method="exact"'
# A light that wraps around periodic x/y ~1e7 times before it leaves: refused before the light
# pass (the exact pass walked every wrap and hung).
SUB=info expect_error "would cross the periodic domain .* times before it leaves" "${small[@]}" --set "grid.periodic=[true,true,false]" --set "sun.direction=[1,0.5,-1e-7]"
expect_error "would cross the periodic domain .* times before it leaves" "${small[@]}" --set "grid.periodic=[true,true,false]" --set "sun.direction=[1,0.5,-1e-7]" --set 'light.method="exact"'
# dom's reflective faces cannot be periodic: info refuses it as run does.
if "$nimbus" info --set "grid.n=[8,8,8]" 2>&1 | grep -q "models in this build:.*dom"; then
  SUB=info expect_error "dom: face x+ cannot be both reflective and periodic" "${small[@]}" --set 'model.name="dom"' --set "grid.periodic=[true,false,false]" --set 'model.dom.reflective=["x+"]'
fi
# A seed beyond 64 bits is refused, not clamped to 2^63 - 1.
SUB=info expect_error "model.montecarlo.seed is beyond the 64-bit integer range" "${small[@]}" --set "model.montecarlo.seed=18446744073709551615"
if [ "$np" -gt 1 ] && "$nimbus" info --set "grid.n=[8,8,8]" 2>&1 | grep -q "models in this build:.*lpm"; then
  expect_error "model lpm needs slabs along z" "${small[@]}" --set 'model.name="lpm"' --set "grid.process_grid=[2,1,1]"
fi

# A run that fails after it created its output folder (here at the periodic-z check, after the
# folder's write test) removes the folders it created, and only those: a folder that existed
# stays, with what was in it.
periodic_sun=("${small[@]}" --set 'model.name="single"' --set "grid.periodic=[false,false,true]" --set 'light.method="exact"')
mkdir -p "$tmp/existing" && touch "$tmp/existing/keep.txt"
for out_dir in "$tmp/new/deeper" "$tmp/existing/sub/" "$tmp/existing"; do
  out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" run "${periodic_sun[@]}" --out "$out_dir" 2>&1); code=$?
  if [ $code -ne 0 ] && echo "$out" | grep -q "is not horizontal" && [ ! -e "$tmp/new" ] && [ ! -e "$tmp/existing/sub" ] &&
     [ -f "$tmp/existing/keep.txt" ] && [ "$(ls -A "$tmp/existing")" = keep.txt ]; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL: a failed run with --out $out_dir left folders behind or removed one (exit $code)"
    ls -laR "$tmp/new" "$tmp/existing" 2>&1 | head; echo "$out" | tail -3
  fi
done

# The output location's checks that need no folder made: `info` refuses as a run does.
touch "$tmp/a_file"
mkdir -p "$tmp/dir_out/nimbus.exr"
SUB=info expect_error "output folder '.*a_file' cannot be created or is not writable: it is a file" "${small[@]}" \
  --set "output.dir=\"$tmp/a_file\""
SUB=info expect_error "output folder '.*a_file/sub' cannot be created: '.*a_file' is a file" "${small[@]}" \
  --set "output.dir=\"$tmp/a_file/sub\""
SUB=info expect_error "cannot write output file '.*dir_out/nimbus.exr': it exists and is not a file" "${small[@]}" \
  --set "output.dir=\"$tmp/dir_out\""
SUB=info expect_error "output '.*ow/nimbus.h5' would overwrite the density file medium.file" "${small[@]}" \
  --set 'medium.kind="raw"' --set "medium.file=\"$tmp/ow/nimbus.h5\"" --set "output.dir=\"$tmp/ow\""

# An output folder that is a symlink to a folder not made yet (out -> /scratch/... before the
# target exists; or a loop) is the user's: a run that fails there keeps the link.
ln -sfn "$tmp/no_such_target" "$tmp/dangling"
ln -sfn "$tmp/loop_b" "$tmp/loop_a" && ln -sfn "$tmp/loop_a" "$tmp/loop_b"
for out_dir in "$tmp/dangling" "$tmp/dangling/sub" "$tmp/loop_a"; do
  out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" run "${small[@]}" --out "$out_dir" 2>&1); code=$?
  if [ $code -ne 0 ] && [ -L "$tmp/dangling" ] && [ -L "$tmp/loop_a" ]; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL: a failed run with --out $out_dir removed the user's symlink (exit $code)"
    ls -la "$tmp" | head; echo "$out" | tail -3
  fi
done

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
