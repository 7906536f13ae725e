#!/usr/bin/env bash
# --help works for the command and every subcommand; `nimbus info` describes a scene.
set -u
nimbus=$1 scenes=${2:-}
fail=0 pass=0
for sub in "" run info compare; do
  out=$("$nimbus" $sub --help 2>&1) || { echo "FAIL: nimbus $sub --help exited non-zero"; fail=$((fail + 1)); continue; }
  if echo "$out" | grep -qi "usage"; then pass=$((pass + 1)); else echo "FAIL: nimbus $sub --help printed no usage"; fail=$((fail + 1)); fi
done
# run and info name the models a scene can ask for, and where every key is documented.
for sub in run info; do
  out=$("$nimbus" $sub --help 2>&1)
  if echo "$out" | grep -q "psf (the path-integral blur model), montecarlo (the reference)" && echo "$out" | grep -q "docs/scene_reference.toml"; then
    pass=$((pass + 1)); else echo "FAIL: nimbus $sub --help does not list the models"; fail=$((fail + 1)); fi
done
if [ -n "$scenes" ]; then
  out=$("$nimbus" info "$scenes/dense_cube.toml" 2>&1)
  for want in "48 x 48 x 48" "vertical optical depth max 20" "memory estimate per rank" "optically thick"; do
    if echo "$out" | grep -q "$want"; then pass=$((pass + 1)); else echo "FAIL: nimbus info lacks '$want'"; echo "$out" | tail -3; fail=$((fail + 1)); fi
  done
  # --log-level debug adds the solvers' per-iteration lines (here DOM's relative change).
  tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
  out=$("$nimbus" --log-level debug run "$scenes/dense_cube.toml" --set 'model.name="dom"' --set "grid.n=[8,8,8]" \
        --set output.image=false --out "$tmp/dbg" 2>&1)
  if echo "$out" | grep -q "\[debug\] dom: dsa iteration 1: relative change"; then pass=$((pass + 1)); else echo "FAIL: --log-level debug shows no iteration lines"; echo "$out" | tail -3; fail=$((fail + 1)); fi
  # A --set of another model's option is accepted but said to be ignored.
  out=$("$nimbus" info "$scenes/dense_cube.toml" --set 'model.name="diffusion"' --set model.dom.order=8 2>&1)
  if echo "$out" | grep -q "\-\-set model.dom.order: ignored, this run's model is 'diffusion'"; then pass=$((pass + 1)); else echo "FAIL: no warning for another model's --set"; echo "$out" | tail -3; fail=$((fail + 1)); fi
  # A scene lit by a volume source: the advice names the models that model sources.
  out=$("$nimbus" info "$scenes/duct.toml" 2>&1)
  if echo "$out" | grep -q "'dom', 'diffusion', 'lpm' and 'montecarlo' model them"; then pass=$((pass + 1)); else echo "FAIL: nimbus info (duct) does not name the models for [[sources]]"; echo "$out" | tail -3; fail=$((fail + 1)); fi
fi
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
