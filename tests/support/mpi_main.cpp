// GoogleTest main for every nimbus test binary, serial or MPI. Initializes MPI, lets rank 0
// print the usual report and the other ranks only their failures (prefixed with the rank), and
// combines pass/fail over all ranks so `mpiexec -n 2 test_x` fails if any rank does.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdio>

#include "src/core/log.h"
#include "src/core/mpi_init.h"

namespace {

// The report of a rank other than 0: each failed assertion and each failed test, nothing else.
class RankFailurePrinter : public ::testing::EmptyTestEventListener {
public:
    explicit RankFailurePrinter(int rank) : rank_(rank) {}
    void OnTestPartResult(const ::testing::TestPartResult& r) override {
        if (!r.failed()) return;
        std::fprintf(stderr, "[rank %d] %s:%d: Failure\n%s\n", rank_, r.file_name() ? r.file_name() : "?",
                     r.line_number(), r.summary());
    }
    void OnTestEnd(const ::testing::TestInfo& t) override {
        if (t.result()->Failed())
            std::fprintf(stderr, "[rank %d] FAILED %s.%s\n", rank_, t.test_suite_name(), t.name());
    }

private:
    int rank_;
};

}  // namespace

int main(int argc, char** argv) {
    nimbus::init_mpi(&argc, &argv);
    ::testing::InitGoogleTest(&argc, argv);
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    nimbus::log::init(rank, "warn");
    if (rank != 0) {
        auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
        delete listeners.Release(listeners.default_result_printer());
        listeners.Append(new RankFailurePrinter(rank));
    }
    int failed = RUN_ALL_TESTS() != 0 ? 1 : 0, any_failed = 0;
    MPI_Allreduce(&failed, &any_failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (rank == 0 && any_failed && !failed) fprintf(stderr, "a test failed on another rank\n");
    MPI_Finalize();
    return any_failed;
}
