#include "src/core/error.h"

#include "src/core/bcast.h"

#include <cstdint>

namespace nimbus {

void check_collective(MPI_Comm comm, bool ok, const std::string& message) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    int mine = ok ? INT32_MAX : rank;
    int first = INT32_MAX;
    MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
    if (first == INT32_MAX) return;
    throw Error(bcast_string(comm, first, message));
}

}  // namespace nimbus
