// sweep::pass_down (solvers/sweep/chain.h): groups passed down the z-slab chain. Every message
// is stamped with (group, sender position, index), so a rank checks that group g brings exactly
// what its upstream neighbour sent for g, in group order, with each group's own size (sizes
// vary, 0 included, and more groups than sends in flight so send buffers are recycled); the
// head receives nothing, the end sends nothing; dir -1 runs the chain the other way, dir 0 has
// no messages; groups that stop early (ChainGroups::last) reach exactly the ranks up to their
// stop; a step that never reads its input does not shift the next group's messages.
#include "solvers/sweep/chain.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

double stamp(int round, int g, int position, size_t i) {
    return 1e8 * round + 1e6 * g + 1e3 * position + static_cast<double>(i);
}

// Sizes 1, 4, 0, 10, 2, 7, 3: more groups than kChainSendsInFlight, growing and shrinking.
sweep::ChainGroups varied_groups() {
    sweep::ChainGroups groups;
    groups.size = {1, 4, 0, 10, 2, 7, 3};
    return groups;
}

// Runs the groups down the chain of dir; checks every message against its stamp. skip_input:
// groups whose step does not call in(); round: stamps messages of repeated passes apart.
void check_chain(const Decomposition& d, int dir, const sweep::ChainGroups& groups,
                 const std::vector<int>& skip_input = {}, int round = 0) {
    const sweep::ChainLink link = sweep::chain_link(d, dir);
    const int ng = static_cast<int>(groups.size.size());
    std::vector<int> ran;
    const sweep::ChainStats stats =
        sweep::pass_down(d, dir, groups, [&](int g, sweep::ChainIO& io) {
            ran.push_back(g);
            const size_t n = groups.size[static_cast<size_t>(g)];
            const int last =
                groups.last.empty() ? link.length - 1 : groups.last[static_cast<size_t>(g)];
            if (std::find(skip_input.begin(), skip_input.end(), g) == skip_input.end()) {
                const auto in = io.in();
                ASSERT_EQ(in.size(), link.position > 0 ? n : 0) << "group " << g;
                for (size_t i = 0; i < in.size(); ++i)
                    ASSERT_EQ(in[i], stamp(round, g, link.position - 1, i)) << "group " << g;
            }
            const auto out = io.out();
            ASSERT_EQ(out.size(), link.position < last ? n : 0) << "group " << g;
            for (size_t i = 0; i < out.size(); ++i) out[i] = stamp(round, g, link.position, i);
        });
    std::vector<int> expected;
    for (int g = 0; g < ng; ++g)
        if (groups.last.empty() || link.position <= groups.last[static_cast<size_t>(g)])
            expected.push_back(g);
    EXPECT_EQ(ran, expected);
    EXPECT_EQ(stats.groups, static_cast<int>(expected.size()));
    EXPECT_GE(stats.wait_seconds, 0.0);
}

TEST(SweepChain, LinkFollowsTheDirection) {
    const Decomposition d(MPI_COMM_WORLD, {4, 3, 9});
    const int p = test::world_size(), z = d.coords()[2];
    ASSERT_EQ(d.dims()[2], p);
    const sweep::ChainLink up = sweep::chain_link(d, 1), down = sweep::chain_link(d, -1),
                           none = sweep::chain_link(d, 0);
    EXPECT_EQ(up.length, p);
    EXPECT_EQ(up.position, z);
    EXPECT_EQ(up.up, z > 0 ? d.neighbor(2, -1) : MPI_PROC_NULL);
    EXPECT_EQ(up.down, z < p - 1 ? d.neighbor(2, 1) : MPI_PROC_NULL);
    EXPECT_EQ(down.position, p - 1 - z);
    EXPECT_EQ(down.up, z < p - 1 ? d.neighbor(2, 1) : MPI_PROC_NULL);
    EXPECT_EQ(down.down, z > 0 ? d.neighbor(2, -1) : MPI_PROC_NULL);
    EXPECT_EQ(none.length, 1);
    EXPECT_EQ(none.position, 0);
    EXPECT_EQ(none.up, MPI_PROC_NULL);
    EXPECT_EQ(none.down, MPI_PROC_NULL);
    for (int dir : {-1, 0, 1})
        EXPECT_EQ(sweep::chain_rank(d, dir, sweep::chain_link(d, dir).position), d.rank());
}

TEST(SweepChain, EachGroupBringsWhatUpstreamSentForIt) {
    const Decomposition d(MPI_COMM_WORLD, {4, 3, 9});
    for (int dir : {1, -1}) check_chain(d, dir, varied_groups());
}

TEST(SweepChain, NoChainSendsNothing) {
    const Decomposition d(MPI_COMM_WORLD, {4, 3, 9});
    check_chain(d, 0, varied_groups());
}

TEST(SweepChain, GroupsStopWhereTheySay) {
    // The exact light pass's pattern: group g stops at position g.
    const Decomposition d(MPI_COMM_WORLD, {4, 3, 9});
    for (int dir : {1, -1}) {
        sweep::ChainGroups groups;
        for (int g = 0; g < d.dims()[2]; ++g) {
            groups.size.push_back(static_cast<size_t>(3 + g));
            groups.last.push_back(g);
        }
        check_chain(d, dir, groups);
    }
}

TEST(SweepChain, AStepThatSkipsItsInputDoesNotShiftTheNextGroup) {
    const Decomposition d(MPI_COMM_WORLD, {4, 3, 9});
    // A message left unreceived by the first pass would be taken by the second.
    for (int dir : {1, -1}) {
        check_chain(d, dir, varied_groups(), {1, 3, 4}, 0);
        check_chain(d, dir, varied_groups(), {}, 1);
    }
}

TEST(SweepChain, PartialSumsAddUpDownTheChain) {
    // Every rank adds its own term to what arrives: the end of the chain holds the sum over
    // all positions, in chain order.
    const Decomposition d(MPI_COMM_WORLD, {4, 3, 9});
    for (int dir : {1, -1}) {
        const sweep::ChainLink link = sweep::chain_link(d, dir);
        sweep::ChainGroups groups;
        groups.size = {5, 2, 6};
        std::vector<std::vector<double>> kept(groups.size.size());
        sweep::pass_down(d, dir, groups, [&](int g, sweep::ChainIO& io) {
            const size_t n = groups.size[static_cast<size_t>(g)];
            std::vector<double> sum(n);
            const auto in = io.in();
            for (size_t i = 0; i < n; ++i)
                sum[i] = (in.empty() ? 0.0 : in[i]) + 0.25 * (link.position + 1) * (g + 1) + i;
            if (io.out().empty())
                kept[static_cast<size_t>(g)] = sum;
            else
                std::copy(sum.begin(), sum.end(), io.out().begin());
        });
        if (link.position != link.length - 1) continue;
        for (size_t g = 0; g < groups.size.size(); ++g) {
            ASSERT_EQ(kept[g].size(), groups.size[g]);
            for (size_t i = 0; i < groups.size[g]; ++i) {
                double ref = 0.0;
                for (int c = 0; c < link.length; ++c)
                    ref =
                        ref + 0.25 * (c + 1) * static_cast<double>(g + 1) + static_cast<double>(i);
                EXPECT_EQ(kept[g][i], ref) << "dir " << dir << " group " << g;
            }
        }
    }
}

}  // namespace
}  // namespace nimbus
