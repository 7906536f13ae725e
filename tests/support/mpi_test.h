// Helpers for tests that run on 1 and 2 ranks.
#pragma once

#include <mpi.h>

namespace nimbus::test {

inline int world_rank() { int r = 0; MPI_Comm_rank(MPI_COMM_WORLD, &r); return r; }
inline int world_size() { int s = 1; MPI_Comm_size(MPI_COMM_WORLD, &s); return s; }

}  // namespace nimbus::test
