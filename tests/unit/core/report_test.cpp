// Run report: nested timer names, max over ranks, memory reported per rank.
#include <gtest/gtest.h>

#include "src/core/report.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

TEST(Report, NestedTimersAndCollectiveSummary) {
    Report r;
    {
        ScopedTimer outer(r, "render");
        { ScopedTimer inner(r, "march"); }
    }
    r.add_time("solve", test::world_rank() == 0 ? 1.0 : 3.0);
    const auto s = r.summarize(MPI_COMM_WORLD);
    ASSERT_EQ(s["phases"].size(), 3u);
    EXPECT_EQ(s["phases"][0]["name"], "render/march");
    EXPECT_EQ(s["phases"][1]["name"], "render");
    EXPECT_EQ(s["phases"][2]["seconds"].get<double>(), test::world_size() == 1 ? 1.0 : 3.0);
    EXPECT_EQ(s["peak_memory_bytes_per_rank"].size(), static_cast<size_t>(test::world_size()));
    EXPECT_GT(s["peak_memory_bytes_per_rank"][0].get<double>(), 1e6);
}

}  // namespace
}  // namespace nimbus
