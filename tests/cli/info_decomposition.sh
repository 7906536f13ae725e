#!/usr/bin/env bash
# `nimbus info` describes the scene, not the decomposition: its optical depths (column sums
# reduced over ranks) are the same whether the ranks split z, x or y, and the largest rank box
# is the largest of all ranks'. The sunlight sweep needs z slabs, so every run here asks for the
# exact light method (info refuses a scene that run would refuse).
set -u
nimbus=$1 mpiexec=$2 np=$3 scenes=$4
pass=0 fail=0
describe() {  # the scene's lines of info for one process grid
  timeout 120 "$mpiexec" -n "$np" "$nimbus" info "$scenes/smoke.toml" --set "grid.n=[32,32,31]" \
    --set "grid.process_grid=$1" --set 'light.method="exact"' 2>/dev/null | grep -E "^(band|medium)"
}
ref=$(describe "[1,1,$np]")
for pg in "[$np,1,1]" "[1,$np,1]"; do
  out=$(describe "$pg")
  if [ -n "$ref" ] && [ "$out" = "$ref" ]; then pass=$((pass + 1)); else
    fail=$((fail + 1)); echo "FAIL: info with process_grid $pg differs from z slabs"; diff <(echo "$ref") <(echo "$out"); fi
done
# Without it, info refuses x slabs before describing anything, with the error run would give.
if [ "$np" -gt 1 ]; then
  out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" info "$scenes/smoke.toml" --set "grid.n=[32,32,31]" \
    --set "grid.process_grid=[$np,1,1]" --set 'light.method="sweep"' 2>&1)
  status=$?
  if [ $status -ne 0 ] && echo "$out" | grep -q 'use light.method = "exact"' && ! echo "$out" | grep -q "^medium:"; then
    pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: info accepted a sweep on x slabs"; echo "$out" | head -5; fi
fi
# 31 layers on 2 ranks: boxes of 15 and 16 layers; the largest is 32 x 32 x 16.
if [ "$np" -eq 2 ]; then
  out=$(timeout 120 "$mpiexec" -n 2 "$nimbus" info "$scenes/smoke.toml" --set "grid.n=[32,32,31]" 2>/dev/null)
  if echo "$out" | grep -q "largest rank box 16384 cells"; then pass=$((pass + 1)); else
    fail=$((fail + 1)); echo "FAIL: largest rank box"; echo "$out" | grep decomposition; fi
fi
# info --ranks N on one process plans what mpiexec -n N gives: the same decomposition and memory
# lines (the largest box's), for z slabs and an x split, and refuses --ranks under other ranks.
plan_lines() { grep -E "^(decomposition|memory estimate)" | sed -e 's/ (planned with --ranks)//' -e 's/; [0-9.]* GiB for the .*//'; }
for pg in "[1,1,$np]" "[$np,1,1]"; do
  args=("$scenes/smoke.toml" --set "grid.n=[32,32,31]" --set "grid.process_grid=$pg" --set 'light.method="exact"')
  real=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" info "${args[@]}" 2>/dev/null | plan_lines)
  planned=$(timeout 120 "$nimbus" info "${args[@]}" --ranks "$np" 2>/dev/null | plan_lines)
  if [ -n "$real" ] && [ "$real" = "$planned" ]; then pass=$((pass + 1)); else
    fail=$((fail + 1)); echo "FAIL: info --ranks $np differs from mpiexec -n $np (process grid $pg)"; diff <(echo "$real") <(echo "$planned"); fi
done
if [ "$np" -gt 1 ]; then
  out=$(timeout 120 "$mpiexec" -n "$np" "$nimbus" info --ranks $((np + 1)) 2>&1); status=$?
  if [ $status -ne 0 ] && echo "$out" | grep -q "plans a run from one process, but $np ranks were started"; then pass=$((pass + 1)); else
    fail=$((fail + 1)); echo "FAIL: --ranks under mpiexec with another count"; echo "$out" | head -3; fi
fi
# A grid planned for many ranks that this process cannot hold: the plan, and the medium not described.
out=$(timeout 120 "$nimbus" info --ranks 4096 --set "grid.n=[4096,4096,4096]" --set 'model.name="dom"' 2>&1); status=$?
if [ $status -eq 0 ] && echo "$out" | grep -q "4096 ranks as 1x1x4096" && echo "$out" | grep -q "for the 4096 ranks together" \
   && echo "$out" | grep -q "^medium: not described"; then pass=$((pass + 1)); else
  fail=$((fail + 1)); echo "FAIL: info --ranks 4096 of a 4096^3 grid (exit $status)"; echo "$out" | tail -3; fi
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
