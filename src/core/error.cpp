#include "src/core/error.h"

#include <vector>

namespace nimbus {

void check_collective(MPI_Comm comm, bool ok, const std::string& message) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    int mine = ok ? INT32_MAX : rank;
    int first = INT32_MAX;
    MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
    if (first == INT32_MAX) return;
    int len = rank == first ? static_cast<int>(message.size()) : 0;
    MPI_Bcast(&len, 1, MPI_INT, first, comm);
    std::string text(static_cast<size_t>(len), '\0');
    if (rank == first) text = message;
    MPI_Bcast(text.data(), len, MPI_CHAR, first, comm);
    throw Error(text);
}

}  // namespace nimbus
