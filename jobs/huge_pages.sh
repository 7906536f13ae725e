# Sourced by jobs/env.sh and jobs/slurm/nimbus.sbatch: large allocations on transparent huge
# pages (glibc >= 2.35 reads GLIBC_TUNABLES at start-up; nothing changes where THP is "never").
# On the virtual machines nimbus is developed on, first touching fresh memory costs one ~12 us
# page fault per 4 KiB (128 MiB: 0.40 s, against 0.017 s on 2 MiB pages), and whole runs of the
# default scene took 11-21% less time with this (README, "Memory and page faults";
# jobs/bench_hugepages.sh). NIMBUS_HUGE_PAGES=0, or a glibc.malloc.hugetlb already in
# GLIBC_TUNABLES, leaves GLIBC_TUNABLES as it was.
if [ "${NIMBUS_HUGE_PAGES:-1}" != 0 ] && [[ ":${GLIBC_TUNABLES:-}:" != *":glibc.malloc.hugetlb="* ]]; then
  export GLIBC_TUNABLES="${GLIBC_TUNABLES:+$GLIBC_TUNABLES:}glibc.malloc.hugetlb=1"
fi
