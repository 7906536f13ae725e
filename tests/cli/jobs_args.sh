#!/usr/bin/env bash
# The benchmark scripts and the study driver refuse bad arguments before running anything: exit
# 1 and one line naming the argument (a size of "abc" used to reach the binaries as 0 and abort
# with a backtrace; a bad model stopped the study only after its long reference run).
#   jobs_args.sh <source dir> <build dir>
set -u
src=$1 build=$2
pass=0 fail=0
expect() {  # expect "<pattern>" command...: exit 1 within 60 s, the pattern on stderr, no table row
  local pattern=$1; shift
  local err code
  err=$(cd "$src" && timeout 60 "$@" 2>&1 >/dev/null); code=$?
  if [ $code -eq 1 ] && echo "$err" | grep -q -- "$pattern"; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL (exit $code, want 1 and /$pattern/): $*"; echo "$err" | tail -3
  fi
}
expect "bench_diffusion.sh: N must be a whole number >= 1, not 'abc'" bash jobs/bench_diffusion.sh "$build" abc
expect "bench_diffusion.sh: N must be a whole number >= 1, not '-5'" bash jobs/bench_diffusion.sh "$build" -5
expect "bench_diffusion.sh: missing /nonexistent/bin/bench_diffusion" bash jobs/bench_diffusion.sh /nonexistent 64
expect "bench_dom.sh: ITERATIONS must be a whole number >= 1, not 'abc'" env ITERATIONS=abc bash jobs/bench_dom.sh "$build" 16
expect "bench_dom.sh: QUADS: 'Q4' is not cube96 or S<order>" env QUADS=Q4 bash jobs/bench_dom.sh "$build" 16
expect "bench_psf.sh: repeats must be a whole number >= 1, not '0'" bash jobs/bench_psf.sh "$build" 16 64 36 0
expect "bench_foundation.sh: N must be a whole number >= 1, not 'x'" bash jobs/bench_foundation.sh "$build" x
expect "bench_lpm.sh: missing /nonexistent/bin/bench_lpm" bash jobs/bench_lpm.sh /nonexistent
expect "bench_montecarlo.sh: photons must be a whole number >= 1, not 'abc'" bash jobs/bench_montecarlo.sh "$build" abc 1
expect "bench_montecarlo.sh: the reference nimbus '/nonexistent' is not an executable" bash jobs/bench_montecarlo.sh "$build" 1000 1 /nonexistent
expect "bench_hugepages.sh: repeats must be a whole number >= 1, not '0'" bash jobs/bench_hugepages.sh "$build" 0
expect "bench_hugepages.sh: ranks must be a whole number >= 1, not 'two'" bash jobs/bench_hugepages.sh "$build" 1 two
expect "bench_hugepages.sh: unknown model 'nosuch'" env MODELS="dom nosuch" bash jobs/bench_hugepages.sh "$build" 1 1
expect "bench_hugepages.sh: missing /nonexistent/bin/nimbus" bash jobs/bench_hugepages.sh /nonexistent
# A nimbus that fails: the script stops with its log, not with empty rows.
expect "bench_montecarlo.sh: /bin/false on 1 rank(s) failed" bash jobs/bench_montecarlo.sh "$build" 1000 1 /bin/false
# study.py: a model nimbus does not know is refused before the reference run (a reference of
# 10^9 photons would take hours), naming the scene and the label.
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
expect "study: scenes/default.toml x: nimbus: error: .*model.name = \"nosuch\" is not allowed" \
  /usr/bin/python3 jobs/study.py --scenes scenes/default.toml --model x=nosuch --ranks 1 \
  --reference-photons 1000000000 --nimbus "$build/bin/nimbus" --out "$tmp/study"
if [ -e "$tmp/study" ]; then fail=$((fail + 1)); echo "FAIL: study.py wrote $tmp/study before refusing"; else pass=$((pass + 1)); fi
# Two scenes of one file name would share OUT/<name> (the second overwriting the first, or
# compared against the first's reference with --reuse-reference).
mkdir -p "$tmp/other" && cp "$src/scenes/slab.toml" "$tmp/other/default.toml"
expect "study: scenes scenes/default.toml, $tmp/other/default.toml would share the folder $tmp/study/default: rename one" \
  /usr/bin/python3 jobs/study.py --scenes scenes/default.toml "$tmp/other/default.toml" --model x=single --ranks 1 \
  --nimbus "$build/bin/nimbus" --out "$tmp/study"
expect "study: --repeats must be >= 1, not 0" \
  /usr/bin/python3 jobs/study.py --scenes scenes/default.toml --model x=single --repeats 0 --out "$tmp/study"
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
