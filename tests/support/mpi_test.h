// Helpers for the tests that run on MPI_COMM_WORLD (registered at 1, 2 and 3 ranks).
#pragma once

#include <mpi.h>

namespace nimbus::test {

inline int world_rank() { int r = 0; MPI_Comm_rank(MPI_COMM_WORLD, &r); return r; }
inline int world_size() { int s = 1; MPI_Comm_size(MPI_COMM_WORLD, &s); return s; }

}  // namespace nimbus::test
