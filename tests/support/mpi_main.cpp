// GoogleTest main for every nimbus test binary, serial or MPI. Initializes MPI, lets only rank
// 0 print, and combines pass/fail over all ranks so `mpiexec -n 2 test_x` fails if any rank does.
#include <gtest/gtest.h>
#include <mpi.h>

#include "src/core/log.h"

int main(int argc, char** argv) {
    MPI_Init(&argc, &argv);
    ::testing::InitGoogleTest(&argc, argv);
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    nimbus::log::init(rank, "warn");
    if (rank != 0) {
        auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
        delete listeners.Release(listeners.default_result_printer());
    }
    int failed = RUN_ALL_TESTS() != 0 ? 1 : 0, any_failed = 0;
    MPI_Allreduce(&failed, &any_failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (rank == 0 && any_failed && !failed) fprintf(stderr, "a test failed on another rank\n");
    MPI_Finalize();
    return any_failed;
}
