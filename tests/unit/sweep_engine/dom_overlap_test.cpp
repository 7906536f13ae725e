// Octant overlap in the DOM transport sweep (solvers/dom/transport_sweep.h, octant_overlap 1, 2,
// 8): the moments, fluence, flux and leakage of a sweep do not depend on how many octants are in
// flight, to round-off (only the order of the octant sums changes), for step and diamond, with
// many and with few tiles, periodic (whose planes start from each octant's own previous sweep,
// so periodic sweeps overlap too) and with reflective faces (where the overlap is
// limited), on 1 and 2 ranks. Source: smooth positive moments and a first-collision beam.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/transport_sweep.h"
#include "tests/unit/sweep_engine/dom_test_source.h"
#include "tests/support/mpi_test.h"

namespace nimbus::dom {
namespace {

struct Case {
    const char* name;
    SpatialScheme scheme;
    int tile_rows;
    std::array<bool, 3> periodic;
    std::array<bool, 6> reflective;
    bool sky = false;
};

// The same for the moments (packed vectors on every cell).
double rel_diff(const std::vector<double>& a, const std::vector<double>& b, MPI_Comm comm) {
    double v[2] = {0.0, 0.0};
    for (size_t q = 0; q < a.size(); ++q) {
        v[0] = std::max(v[0], std::abs(a[q] - b[q]));
        v[1] = std::max(v[1], std::abs(b[q]));
    }
    MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_DOUBLE, MPI_MAX, comm);
    return v[0] / v[1];
}

SweepOutput sweep_once(const Decomposition& d, const AngularSet& ang, const Case& c, int overlap) {
    const Box& own = d.local();
    Field<double> kappa(own, 0, 1, 0.0), moments(own, 0, ang.nmom, 0.0), amp(own, 0, 1, 0.0);
    for_each_cell(own, [&](int i, int j, int k) {
        kappa(i, j, k) = 0.5 + 0.05 * ((i + 2 * j + 3 * k) % 7);
        for (int m = 0; m < ang.nmom; ++m) moments(i, j, k, m) = (m == 0 ? 1.0 : 0.1 / (1 + m)) * (1.0 + 0.1 * i - 0.05 * k);
        amp(i, j, k) = std::exp(-0.2 * (d.global().hi[2] - k));
    });
    const SweepSource src = test_source::make(ang, kappa, moments, amp);
    sweep::SweepOptions opt;
    opt.tile_rows = c.tile_rows;
    opt.octant_overlap = overlap;
    SweepBoundary bc;
    bc.reflective = c.reflective;
    bc.sky = c.sky;
    TransportSweeper sweeper(d, ang, 1.0, opt, 1e-12, c.scheme, bc);
    sweeper.set_sky_radiance(0.7);
    SweepOutput out;
    sweeper.sweep(src, out);
    sweeper.sweep(src, out);  // the second sweep sees the lagged reflections of the first
    return out;
}

TEST(DomOctantOverlap, SweepResultDoesNotDependOnTheOverlap) {
    const AngularSet ang = make_angular_set(level_symmetric(4), 3);
    const std::array<bool, 6> none{};
    const std::array<bool, 6> refl_high{false, true, false, false, false, true};  // x+, z+: overlap kept
    const std::array<bool, 6> refl_x_low{true, false, false, false, false, false};  // x-: 8 limited to 2
    const std::array<bool, 6> refl_low{true, false, false, false, true, false};        // x-, z-: limited to 1
    const Case cases[] = {
        {"step, tile_rows 2", SpatialScheme::step, 2, {false, false, false}, none},
        {"step, one tile", SpatialScheme::step, 100, {false, false, false}, none},
        {"diamond, tile_rows 3", SpatialScheme::diamond, 3, {false, false, false}, none},
        {"step, periodic x", SpatialScheme::step, 2, {true, false, false}, none},
        {"diamond, periodic x y", SpatialScheme::diamond, 2, {true, true, false}, none},
        {"step, reflective x+ z+", SpatialScheme::step, 2, {false, false, false}, refl_high},
        {"step, reflective x-", SpatialScheme::step, 2, {false, false, false}, refl_x_low},
        {"step, reflective x- z-", SpatialScheme::step, 2, {false, false, false}, refl_low},
        {"step, sky", SpatialScheme::step, 2, {false, false, false}, none, true},
    };
    for (const Case& c : cases) {
        const Decomposition d(MPI_COMM_WORLD, {6, 5, 8}, {0, 0, 0}, c.periodic);
        const SweepOutput ref = sweep_once(d, ang, c, 1);
        for (int overlap : {2, 8}) {
            const SweepOutput out = sweep_once(d, ang, c, overlap);
            ASSERT_EQ(out.phi.size(), ref.phi.size());
            EXPECT_LT(rel_diff(out.phi, ref.phi, d.comm()), 1e-13) << c.name << ", overlap " << overlap;
            EXPECT_LT(test_source::rel_diff(out.fluence, ref.fluence, ref.fluence, d.comm()), 1e-13)
                << c.name << ", overlap " << overlap;
            // |F| <= fluence: the flux's round-off scale (its octant sums cancel)
            EXPECT_LT(test_source::rel_diff(out.flux, ref.flux, ref.fluence, d.comm()), 1e-13)
                << c.name << ", overlap " << overlap;
            for (int f = 0; f < 6; ++f)
                EXPECT_NEAR(out.leakage[static_cast<size_t>(f)], ref.leakage[static_cast<size_t>(f)],
                            1e-12 * (1.0 + std::abs(ref.leakage[static_cast<size_t>(f)])))
                    << c.name << ", overlap " << overlap << ", face " << f;
        }
    }
}

}  // namespace
}  // namespace nimbus::dom
