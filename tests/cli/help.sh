#!/usr/bin/env bash
# --help works for the command and every subcommand.
set -u
nimbus=$1
fail=0
for sub in "" run info compare; do
  out=$("$nimbus" $sub --help 2>&1) || { echo "FAIL: nimbus $sub --help exited non-zero"; fail=1; }
  echo "$out" | grep -qi "usage" || { echo "FAIL: nimbus $sub --help printed no usage"; fail=1; }
done
[ $fail -eq 0 ] && echo "1 passed, 0 failed" || echo "0 passed, 1 failed"
exit $fail
