#!/usr/bin/env bash
# The command line as a user meets it, on one rank: usage errors are one "nimbus: error:" line
# naming the bad argument with a hint, exit status 1; the global options may follow the
# subcommand; `nimbus info` makes the checks a run makes (and refuses a grid that does not fit
# in memory without allocating it); `nimbus compare` names the fields it supports and warns
# when A and B are runs of different media.
set -u
nimbus=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0

# check "<what>" <want exit> "<grep pattern>" args...: exit status, one error line at most, pattern.
check() {
  local what=$1 want=$2 pattern=$3; shift 3
  local out code lines
  out=$(timeout 120 "$nimbus" "$@" 2>&1); code=$?
  lines=$(echo "$out" | grep -c "nimbus: error:")
  if [ "$code" -eq "$want" ] && { [ "$want" -eq 0 ] || [ "$lines" -eq 1 ]; } && echo "$out" | grep -q -- "$pattern"; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1))
    echo "FAIL: $what (exit $code, want $want; $lines error lines; want /$pattern/): nimbus $*"
    echo "$out" | tail -5
  fi
}

small=(--set "grid.n=[12,12,8]" --set "camera.resolution=[16,12]")

# Usage errors: exit 1, the bad argument named, a pointer to --help.
check "unknown command" 1 "nimbus: error: unknown command 'bogus'; commands: run, info, compare (see nimbus --help)" bogus
check "no command" 1 "a command is required.*nimbus --help" 
check "unknown option" 1 "nimbus: error:.*--bogus.*nimbus run --help" run --bogus
check "bad log level" 1 "nimbus: error: --log-level: loud" --log-level loud info
check "missing file" 1 "nimbus: error:.*no_such.h5" compare "$tmp/no_such.h5" "$tmp/no_such.h5"
check "missing argument" 1 "nimbus: error:.*nimbus compare --help" compare
check "option without command" 1 "unknown option '--bogus' and no command; commands: run, info, compare" --bogus
check "empty --out" 1 "nimbus: error: --out: the folder name is empty" run --out ""
check "info --out" 1 "nimbus: error: --out: info writes no files" info --out "$tmp" "${small[@]}"
check "int option beyond int" 1 "model.diffusion.max_iterations = 99999999999 is too large (at most 2147483647)" info --set "model.diffusion.max_iterations=99999999999"
check "limiter option without limiter" 1 'model.diffusion.limiter_iterations = 5 is read only with flux_limiter = "levermore-pomraning"' info --set 'model.name="diffusion"' --set "model.diffusion.limiter_iterations=5"
check "limiter option blamed" 1 '\-\-set model.diffusion.limiter_tolerance=0.5: model.diffusion.limiter_tolerance = 0.5 is read only' info --set 'model.name="diffusion"' --set 'model.diffusion.flux_limiter="none"' --set "model.diffusion.limiter_tolerance=0.5"
# Another model's settings are read for their ranges only: diffusion's cross-key rules apply when it runs.
check "other model's diffusion options" 0 "--set model.diffusion.petsc_options: ignored, this run's model is 'dom'" info --set 'model.name="dom"' --set 'model.diffusion.petsc_options="-diffusion_pc_type jacobi"' --set "model.diffusion.limiter_iterations=5"
# Settings of the run's own model that its other settings leave unread are said (a QA finding).
check "dom polar without the product set" 0 "model.dom.polar and azimuthal are read only with quadrature = \"product\" (this run's is 'level-symmetric'): ignored" info --set 'model.name="dom"' --set model.dom.polar=4
check "dom order with the product set" 0 "model.dom.order is read only with quadrature = \"level-symmetric\" (this run's is 'product'): ignored" info --set 'model.name="dom"' --set 'model.dom.quadrature="product"' --set model.dom.order=8
check "samples_per_pixel without the path-traced image" 0 "model.montecarlo.samples_per_pixel is read only with model.montecarlo.image = true: ignored" info --set model.montecarlo.samples_per_pixel=16
check "psf levels beyond the grid" 0 "model.psf.levels = 100: this grid allows [0-9]* pyramid levels, and those are used" run --set 'model.name="psf"' --set model.psf.levels=100 "${small[@]}" --set output.image=false --out "$tmp/psf"
check "ground albedo without the ground" 0 "background.ground_albedo and ground_color are read only with background.kind = \"ground\": ignored" info --set background.ground_albedo=0.5
check "emission colour when scattering" 0 "render.emission_color is read only with render.mode = \"emission\" or \"emission_absorption\": ignored" info --set render.emission_color=0.5
check "ray-march step with the path-traced image" 0 "render.step and early_termination are the ray caster's" info --set model.montecarlo.image=true --set render.step=0.25
check "path-traced image without an image" 0 "model.montecarlo.image = true, but output.image = false: no image is made" info --set model.montecarlo.image=true --set output.image=false
# P1 far below zero (no delta scaling: the first-scatter flux source overwhelms it) is said, not hidden by the clamp.
check "negative U warned" 0 "diffusion (bands r, g, b): U is negative in .* cells" run --set 'model.name="diffusion"' \
  --set "grid.n=[24,24,16]" --set grid.cell_size=100 --set model.diffusion.delta_scaling=false --set output.image=false --out "$tmp/neg"
check "grid.n beyond int" 1 "grid.n entry 0 = 3000000000 is outside the range of a 32-bit integer" info --set "grid.n=[3000000000,2,2]"
check "density file is a folder" 1 "medium.file = \"$tmp\" is a directory" info --set 'medium.kind="raw"' --set "medium.file=\"$tmp\""
# info's description is its output (stdout, whatever the log level); the log (stderr) is quiet at
# --log-level warn, given after the subcommand.
out=$("$nimbus" info "${small[@]}" --log-level warn 2>"$tmp/info.err"); code=$?
if [ $code -eq 0 ] && echo "$out" | grep -q "^grid: 12 x 12 x 8" && echo "$out" | grep -q "^model asked for:" \
   && [ ! -s "$tmp/info.err" ]; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: info to stdout, --log-level warn (exit $code)"; echo "$out" | tail -3; cat "$tmp/info.err"; fi
check "log level after the subcommand" 0 "decomposition:" info "${small[@]}" --log-level debug
# Monte Carlo traces one batch per rank per round: ranks that would wait are said before the run.
check "montecarlo: idle ranks warned" 0 "batches = 32 on 64 ranks: .* so 32 ranks trace nothing .* batches = 64" info --ranks 64
out=$("$nimbus" info --ranks 64 --set model.montecarlo.batches=128 2>&1); code=$?
if [ $code -eq 0 ] && ! echo "$out" | grep -q "trace nothing"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: montecarlo batches a multiple of the ranks warns (exit $code)"; echo "$out" | tail -3; fi

# A --set medium key that the medium's kind does not read is said (the default medium is a cumulus).
check "medium key of another kind warned" 0 "\-\-set medium.sphere_radius: ignored, medium.kind is 'cumulus' (it applies to sphere)" \
  info "${small[@]}" --set medium.sphere_radius=0.2
out=$("$nimbus" info "${small[@]}" --set 'medium.kind="sphere"' --set medium.sphere_radius=0.2 2>&1); code=$?
if [ $code -eq 0 ] && ! echo "$out" | grep -q "ignored"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: a medium key of the kind warns (exit $code)"; echo "$out" | tail -3; fi
# An output this run does not write, left by an earlier run under the same name, is said.
"$nimbus" run "${small[@]}" --out "$tmp/left" > /dev/null 2>&1
check "output left by an earlier run warned" 0 "output.hdf5 = false: .*left/nimbus.h5 (and its .xdmf) from an earlier run stays" \
  run "${small[@]}" --set output.hdf5=false --out "$tmp/left"

# A big-endian raw file (0.5 everywhere) read as little-endian: densities of 8.8e-44, said.
/usr/bin/python3 -c "import struct; open('$tmp/be.raw', 'wb').write(struct.pack('>1152f', *([0.5] * 1152)))"
check "big-endian raw file warned" 0 "the medium is practically transparent: its densest cell is 8.83e-44 .* is the file big-endian?" \
  run "${small[@]}" --set 'medium.kind="raw"' --set "medium.file=\"$tmp/be.raw\"" --set output.image=false --out "$tmp/be"

# psf on cells of many optical depths (too bright there): said.
check "psf on thick cells warned" 0 "model psf: cells up to 1[0-9.]* optical depths thick: .* too bright" \
  run "${small[@]}" --set 'model.name="psf"' --set medium.density=12 --out "$tmp/psf_thick"

# info refuses what run refuses, with the same message.
check "info: duplicate band name" 1 "optics\[1\].name = \"r\" repeats optics\[0\].name" info --set 'optics[1].name="r"'
check "info: band name with /" 1 "optics\[2\].name = \"b/x\" is not a valid band name" info --set 'optics[2].name="b/x"'
check "info: empty band name" 1 "optics\[0\].name must not be empty" info --set 'optics[0].name=""'
check "info: model auto" 1 "model.name = \"auto\" is not allowed" info --set 'model.name="auto"'
check "info: model none" 1 "model.name = \"none\" is not allowed" info --set 'model.name="none"'
check "info: camera sees nothing" 1 "camera.look_at: the camera looks at nothing" info --set "camera.look_at=[0.5,-3,0.42]"
check "info: empty medium" 0 "no non-empty cells" info "${small[@]}" --set medium.density=0
# A grid far beyond any machine: the estimate, then a clear error, and nothing allocated.
check "info: grid too large" 1 "the grid does not fit in memory.*use more ranks" info --set "grid.n=[65536,65536,65536]" --set 'model.name="single"'
# Monte Carlo copies the grid to every rank: more ranks on the node would not help.
check "info: grid too large, montecarlo" 1 "the grid does not fit in memory.*run fewer ranks per node" info --set "grid.n=[65536,65536,65536]"
check "info: grid too large, estimate" 1 "memory estimate per rank" info --set "grid.n=[65536,65536,65536]"
check "run: grid too large" 1 "the grid does not fit in memory.*use more ranks" run --set "grid.n=[65536,65536,65536]" --set 'model.name="dom"' --out "$tmp/big"
# An allocation that fails anyway (here under a 1 GB address-space limit) is a clear error too.
out=$( (ulimit -v 1000000; timeout 120 "$nimbus" run --set "grid.n=[256,256,256]" --set 'medium.kind="box"' \
        --set output.image=false --out "$tmp/big" 2>&1) ); code=$?
if [ $code -eq 1 ] && echo "$out" | grep -q "nimbus: error: not enough memory on rank 0; use more ranks.*nimbus info" \
   && ! echo "$out" | grep -q "internal error"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: bad_alloc (exit $code)"; echo "$out" | tail -3; fi

# compare: two runs of one medium, a third of another.
run_small() { "$nimbus" run "${small[@]}" --set output.image=false --out "$tmp/$1" "${@:2}" > /dev/null 2>&1; }
if run_small a && run_small a2 && run_small b --set medium.density=2.0; then
  a=$tmp/a/nimbus.h5 a2=$tmp/a2/nimbus.h5 b=$tmp/b/nimbus.h5
  check "compare: vector field" 1 "unsupported field 'flux_diffuse'; choose fluence_diffuse | fluence_reduced | transmittance_sun" compare "$a" "$a2" --field flux_diffuse
  check "compare: unknown field" 1 "unsupported field 'foo'; choose fluence_diffuse" compare "$a" "$a2" --field foo
  check "compare: other field" 0 "transmittance_sun of" compare "$a" "$a2" --field transmittance_sun
  out=$("$nimbus" compare "$a" "$a2" 2>&1); code=$?
  if [ $code -eq 0 ] && ! echo "$out" | grep -q "differ"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: compare of one medium warns (exit $code)"; echo "$out" | tail -3; fi
  check "compare: different media warn" 0 "the density fields of .* differ" compare "$a" "$b"
  out=$("$nimbus" compare "$a" "$b" --json 2>/dev/null); code=$?
  if [ $code -eq 0 ] && echo "$out" | /usr/bin/python3 -c 'import json, sys; r = json.load(sys.stdin); sys.exit(0 if r["same_medium"] is False and r["density_max_rel_diff"] > 0.1 else 1)'; then
    pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: compare --json does not flag different media (exit $code)"; echo "$out" | head -8; fi
  out=$("$nimbus" compare "$a" "$a2" --json 2>/dev/null)
  if echo "$out" | /usr/bin/python3 -c 'import json, sys; sys.exit(0 if json.load(sys.stdin)["same_medium"] is True else 1)'; then
    pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: compare --json flags one medium as different"; fi
  # The same densities on larger cells are another medium too (the cell size from /scene).
  if run_small c --set grid.cell_size=30; then
    c=$tmp/c/nimbus.h5
    check "compare: other cell size warns" 0 "the cells of .* differ in size (25 m against 30 m)" compare "$a" "$c"
    out=$("$nimbus" compare "$a" "$c" --json 2>/dev/null)
    if echo "$out" | /usr/bin/python3 -c 'import json, sys; r = json.load(sys.stdin); sys.exit(0 if r["same_medium"] is False and r["density_max_rel_diff"] == 0 and r["cell_size_m_b"] == 30 else 1)'; then
      pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: compare --json does not flag another cell size"; echo "$out" | head -8; fi
  else
    fail=$((fail + 1)); echo "FAIL: the small run with other cells did not run"
  fi
  # The cell size is read from /scene also when the reference's imported density is gone (the
  # stored scene names a file that no longer exists; compare reads only its grid and bands).
  /usr/bin/python3 -c 'import struct, sys; open(sys.argv[1], "wb").write(struct.pack("<1152f", *([0.5] * 1152)))' "$tmp/d.raw"
  if run_small d --set 'medium.kind="raw"' --set "medium.file=\"$tmp/d.raw\"" --set grid.cell_size=30; then
    rm "$tmp/d.raw"
    check "compare: cell size of a run whose density file is gone" 0 "the cells of .* differ in size (25 m against 30 m)" compare "$a" "$tmp/d/nimbus.h5"
  else
    fail=$((fail + 1)); echo "FAIL: the small run of an imported density did not run"
  fi
  # A reference whose few paths left cells unreached: RMS z is over the others, and says so.
  if run_small few --set model.montecarlo.photons=300 --set model.montecarlo.batches=4; then
    check "compare: RMS z over the reached cells" 0 "r: RMS z over [0-9]* of the [0-9]* cells; on the others the standard error of .* is 0 or at least half the value" compare "$a" "$tmp/few/nimbus.h5"
  else
    fail=$((fail + 1)); echo "FAIL: the small run with few photons did not run"
  fi
else
  fail=$((fail + 1)); echo "FAIL: the small runs for compare did not run"
fi

# A killed run's temporary (its process gone) is said, not left unmentioned.
mkdir -p "$tmp/stale"; head -c 1000 /dev/zero > "$tmp/stale/nimbus.h5.4194300-0badcafe.tmp"
check "run: a killed run's temporary is said" 0 "\[warning\] 1 temporary file of an earlier, killed run" \
  run "${small[@]}" --set 'model.name="single"' --set output.image=false --out "$tmp/stale"
# A run that shows nothing (no light, or no medium) runs, and says so once.
check "run: no light warns" 0 "\[warning\] the scene has no light" run "${small[@]}" --set sun.enabled=false --set sky.radiance=0 --set output.image=false --out "$tmp/dark"
# ... psf too (it used to refuse: "no light to blur"), with its image of the background.
if "$nimbus" info --set "grid.n=[8,8,8]" 2>&1 | grep -q "models in this build:.*psf"; then
  check "run: psf without light warns" 0 "\[warning\] the scene has no light" run "${small[@]}" --set 'model.name="psf"' --set sun.enabled=false --set sky.radiance=0 --out "$tmp/dark_psf"
fi
check "run: a sun below the horizon over a ground warns" 0 "\[warning\] sun.direction points upward" run "${small[@]}" --set 'model.name="single"' --set "sun.direction=[0.3,0.2,0.9]" --set 'background.kind="ground"' --set output.image=false --out "$tmp/below"
# Negative fluence is said, by lpm as by dom (QA: lpm's DSA left -3% of the peak at g = 0.99, silently).
box=(--set "grid.n=[8,8,8]" --set 'medium.kind="box"' --set "medium.box_lo=[0.25,0.25,0.25]" --set "medium.box_hi=[0.75,0.75,0.75]"
     --set 'optics=[{name="gray",sigma_t=2.0,albedo=0.9,g=0.99}]' --set "sun.direction=[0,0,-1]" --set sun.irradiance=1
     --set sky.radiance=0 --set background.color=0 --set output.image=false)
check "run: lpm's negative fluence warns" 0 "\[warning\] lpm (band gray): fluence_diffuse is below -0.001 of its largest value" \
  run "${box[@]}" --set 'model.name="lpm"' --out "$tmp/lpm_negative"
# Cells of several optical depths: lpm's P1 tail is far too bright (1.7x Monte Carlo's total at 5 per cell), the
# finite-volume models do not resolve the field: said.
check "info: thick cells are said" 0 "cells up to 5 optical depths thick: lpm's P1 tail comes out too bright" \
  info "${box[@]}" --set grid.cell_size=1 --set 'optics=[{name="gray",sigma_t=5.0,albedo=0.999,g=0.0}]'
check "run: diffusion on thick cells warns" 0 "\[warning\] model diffusion: cells up to 5 optical depths thick" \
  run "${box[@]}" --set grid.cell_size=1 --set 'optics=[{name="gray",sigma_t=5.0,albedo=0.999,g=0.0}]' --set 'model.name="diffusion"' --out "$tmp/thick"
check "run: dom on thick cells warns" 0 "\[warning\] model dom: cells up to 5 optical depths thick" \
  run "${box[@]}" --set grid.cell_size=1 --set 'optics=[{name="gray",sigma_t=5.0,albedo=0.9,g=0.0}]' --set 'model.name="dom"' --out "$tmp/thick_dom"
# dom's step scheme over-diffuses by (3/4) kappa (1 - a g) h: on a bright box at 1.25 optical depths per cell
# its fluence is 0.63-0.78 of Monte Carlo's (solvers/dom/dom.cpp, warn_if_step_diffuses): said, with the cure.
check "run: dom's step scheme on bright thick cells warns" 0 "\[warning\] model dom: the step scheme diffuses light 94% more than it should .*kappa (1 - a g) h = 1.25, band 'gray', albedo 0.999.*scheme = 'diamond'" \
  run "${box[@]}" --set grid.cell_size=1 --set 'optics=[{name="gray",sigma_t=1.25,albedo=0.999,g=0.0}]' --set 'model.name="dom"' --out "$tmp/step_dom"
# Under a grazing sun over periodic x/y the cells' means of T took 1.9x the beam (QA); bounded and said.
check "run: first-scatter bound warns" 0 "\[warning\] first-scatter source of light 'sun' in band 'gray': .* scaled down by 0\.523" \
  run "${box[@]}" --set "grid.n=[12,12,12]" --set grid.cell_size=1 --set "grid.periodic=[true,true,false]" \
  --set 'optics=[{name="gray",sigma_t=0.5,albedo=0.9,g=0.0}]' --set "sun.direction=[1.0,0.7,-0.02]" \
  --set 'model.name="dom"' --out "$tmp/grazing"
check "run: no medium warns" 0 "\[warning\] the medium has no non-empty cells" run "${small[@]}" --set medium.density=0 --set output.image=false --out "$tmp/empty"

# An interrupted run (Ctrl-C, SIGTERM from a batch system) leaves no temporary and removes the
# folders it created, like a failed run: wait until the run has made its output folder, then
# interrupt it during its (long) Monte Carlo phase. A background job of a script starts with
# SIGINT ignored, and nimbus keeps an ignored signal ignored (nohup): env gives it back.
for sig in INT TERM; do
  env --default-signal=INT,TERM "$nimbus" run "${small[@]}" --set 'model.name="montecarlo"' \
      --set model.montecarlo.photons=2000000000 --out "$tmp/killed_$sig/sub" > "$tmp/killed.log" 2>&1 &
  pid=$!
  for _ in $(seq 300); do [ -d "$tmp/killed_$sig/sub" ] && break; sleep 0.1; done
  made=no; [ -d "$tmp/killed_$sig/sub" ] && made=yes
  sleep 0.5
  kill -s "$sig" "$pid"
  for _ in $(seq 200); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  ended=yes; if kill -0 "$pid" 2>/dev/null; then ended=no; kill -KILL "$pid"; fi
  wait "$pid"; code=$?
  said=no; grep -q "nimbus: interrupted: removed this run's temporary files and new folders" "$tmp/killed.log" && said=yes
  if [ "$made" = yes ] && [ "$ended" = yes ] && [ "$said" = yes ] && [ "$code" -eq $((128 + $(kill -l "$sig"))) ] && [ ! -e "$tmp/killed_$sig" ]; then
    pass=$((pass + 1)); else
    fail=$((fail + 1)); echo "FAIL: SIG$sig: folder made $made, ended by the signal $ended, said so $said, exit $code, left behind:"
    find "$tmp/killed_$sig" 2>&1 | head -5; tail -3 "$tmp/killed.log"; fi
done
# Interrupted while solving into a folder that exists: nothing to remove, and it says so too
# (it used to end silently after its last progress line).
mkdir -p "$tmp/existing_int"
env --default-signal=INT "$nimbus" run "${small[@]}" --set 'model.name="montecarlo"' \
    --set model.montecarlo.photons=2000000000 --out "$tmp/existing_int" > "$tmp/int.log" 2>&1 &
pid=$!
for _ in $(seq 300); do grep -q "montecarlo" "$tmp/int.log" 2>/dev/null && break; sleep 0.1; done
sleep 0.5; kill -INT "$pid"; wait "$pid"; code=$?
if [ "$code" -eq 130 ] && grep -q "nimbus: interrupted before writing any output: the output folder is as it was" "$tmp/int.log" &&
   [ -z "$(ls -A "$tmp/existing_int")" ]; then pass=$((pass + 1)); else
  fail=$((fail + 1)); echo "FAIL: interrupted into an existing folder (exit $code):"; tail -3 "$tmp/int.log"; fi
# A signal the run was started with ignored stays ignored (nohup): the run goes on.
env --ignore-signal=HUP "$nimbus" run "${small[@]}" --set 'model.name="montecarlo"' \
    --set model.montecarlo.photons=2000000000 --out "$tmp/nohup" > /dev/null 2>&1 &
pid=$!
for _ in $(seq 300); do [ -d "$tmp/nohup" ] && break; sleep 0.1; done
sleep 0.5; kill -HUP "$pid"; sleep 1
if kill -0 "$pid" 2>/dev/null && [ -d "$tmp/nohup" ]; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: an ignored SIGHUP ended the run"; fi
kill -KILL "$pid" 2>/dev/null; wait "$pid" 2>/dev/null

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
