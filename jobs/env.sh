# Sourced by the scripts: what Open MPI needs to run as root and on few cores. A user never has
# to set these by hand.
export OMPI_ALLOW_RUN_AS_ROOT=1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_hwloc_base_binding_policy=none
# Debian's python3 has numpy/h5py/matplotlib; a pyenv python first on PATH may not.
NIMBUS_PYTHON=/usr/bin/python3
# Large allocations on transparent huge pages (GLIBC_TUNABLES; see the file).
source "$(dirname "${BASH_SOURCE[0]:-jobs/env.sh}")/huge_pages.sh"
