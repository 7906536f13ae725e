// Procedural media: independent of the decomposition, bounded, and the checks refuse bad values.
#include <gtest/gtest.h>

#include <cmath>

#include "src/core/error.h"
#include "src/scene/medium.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

TEST(Medium, CumulusIsDeterministicBoundedAndNonTrivial) {
    MediumSpec spec;  // default cumulus
    const ProceduralDensity a(spec, {32, 32, 24}), b(spec, {32, 32, 24});
    double maxv = 0, filled = 0;
    for_each_cell(Box{{0, 0, 0}, {32, 32, 24}}, [&](int i, int j, int k) {
        const double v = a(i, j, k);
        ASSERT_EQ(v, b(i, j, k));
        ASSERT_GE(v, 0.0);
        ASSERT_LE(v, 1.0);
        maxv = std::max(maxv, v);
        filled += v > 0;
    });
    EXPECT_GT(maxv, 0.9);
    EXPECT_GT(filled, 0.05 * 32 * 32 * 24);   // a cloud, not a speck
    EXPECT_LT(filled, 0.6 * 32 * 32 * 24);    // with empty space around it
    EXPECT_EQ(a(0, 0, 0), 0.0);               // corners are clear sky
}

TEST(Medium, BoxAndSphereKinds) {
    MediumSpec spec;
    spec.kind = MediumSpec::Kind::box;
    spec.density = 2.5;
    spec.box_lo = {0.25, 0.0, 0.5};
    spec.box_hi = {0.75, 1.0, 1.0};
    const ProceduralDensity box(spec, {8, 8, 8});
    EXPECT_EQ(box(2, 0, 4), 2.5);
    EXPECT_EQ(box(1, 0, 4), 0.0);
    EXPECT_EQ(box(5, 7, 7), 2.5);
    EXPECT_EQ(box(5, 7, 3), 0.0);
    spec.kind = MediumSpec::Kind::sphere;
    const ProceduralDensity sph(spec, {9, 9, 9});
    EXPECT_EQ(sph(4, 4, 4), 2.5);
    EXPECT_EQ(sph(0, 0, 0), 0.0);
}

TEST(Medium, FilledFieldMatchesOnEveryDecomposition) {
    MediumSpec spec;
    const Int3 n{16, 12, 10};
    const Decomposition d(MPI_COMM_WORLD, n);
    Field<double> rho(d.local(), 1, 1, 0.0);
    fill_procedural_density(spec, d, rho);
    const ProceduralDensity ref(spec, n);
    for_each_cell(d.local().grown(1), [&](int i, int j, int k) {
        const bool inside = Box{{0, 0, 0}, n}.contains(i, j, k);
        ASSERT_EQ(rho(i, j, k), inside ? ref(i, j, k) : 0.0);
    });
}

TEST(Medium, CheckDensityRefusesNegativeAndNaNOnEveryRank) {
    const Decomposition d(MPI_COMM_WORLD, {4, 4, 4});
    Field<double> rho(d.local(), 1, 1, 0.5);
    EXPECT_NO_THROW(check_density(rho, d));
    if (d.rank() == d.size() - 1) rho(1, 1, d.local().lo[2]) = std::nan("");
    EXPECT_THROW(check_density(rho, d), Error);  // thrown on every rank, none hangs
    rho.fill(0.5);
    if (d.rank() == 0) rho(0, 0, 0) = -1.0;
    EXPECT_THROW(check_density(rho, d), Error);
    // Beyond float32 (the output's type): 1e300 is finite in double but Inf in the file.
    rho.fill(0.5);
    if (d.rank() == d.size() - 1) rho(2, 2, d.local().lo[2]) = 1e300;
    EXPECT_THROW(check_density(rho, d), Error);
    rho.fill(0.5);
    rho(0, 0, d.local().lo[2]) = 3e38;  // the largest float is 3.4e38: still accepted
    EXPECT_NO_THROW(check_density(rho, d));
}

}  // namespace
}  // namespace nimbus
