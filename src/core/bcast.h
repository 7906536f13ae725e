// Broadcast of a string (its length, then its bytes): root's s on every rank of comm. Collective.
#pragma once

#include <mpi.h>

#include <string>

namespace nimbus {

inline std::string bcast_string(MPI_Comm comm, int root, const std::string& s) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    int len = rank == root ? static_cast<int>(s.size()) : 0;
    MPI_Bcast(&len, 1, MPI_INT, root, comm);
    std::string out = rank == root ? s : std::string(static_cast<size_t>(len), '\0');
    MPI_Bcast(out.data(), len, MPI_CHAR, root, comm);
    return out;
}

}  // namespace nimbus
