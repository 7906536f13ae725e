// Pure absorber with a uniform isotropic volume source q (no scattering): the discrete-angle
// answer is exact along every ordinate, psi_n(z) = (q/kappa)(1 - exp(-kappa d_n/|mu_n|)), d_n
// the distance to the upwind boundary, so the fluence error is the spatial scheme's alone.
// Also: the energy balance of the sweep (source = absorbed + leaked) with scattering.
#include <gtest/gtest.h>

#include <cmath>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/band_problem.h"
#include "solvers/dom/dom.h"
#include "solvers/dom/iteration.h"
#include "tests/support/mpi_test.h"
#include "tests/verification/dom/dom_world.h"

namespace nimbus {
namespace {

// Max fluence error (relative to 4π q/kappa) of a periodic 4x4xnz absorbing slab of thickness Z (kappa = 1).
double absorber_slab_error(int nz, double Z, int order, double* interior_error = nullptr) {
    const double h = Z / nz, q = 1.0;
    test::DomWorld w(MPI_COMM_WORLD, {4, 4, nz}, h, BandOptics{"gray", 1.0, 0.0, 0.0}, {true, true, false});
    DomOptions o;
    o.order = order;
    const dom::AngularSet ang = dom::make_angular_set(o);
    dom::BandProblem p = dom::make_band_optics(w.m, 0, w.d.local(), ang, true);
    p.emission.fill(q);
    dom::add_light_sources(p, w.d, w.m, w.light, 0, ang);
    dom::TransportSweeper sweeper(w.d, ang, h, {}, 1e-12);
    dom::SweepOutput out;
    const auto r = dom::iterate_band(w.d, sweeper, ang, p, "source", 1e-12, 5, out, w.report);
    EXPECT_TRUE(r.converged);
    EXPECT_LE(r.iterations, 3);  // no scattering: the next sweeps repeat the first (to the periodic tolerance)
    double err = 0.0, interior = 0.0;
    const auto& qd = ang.quadrature;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        const double z = (k + 0.5) * h;
        double exact = 0.0;
        for (int n = 0; n < qd.size(); ++n) {
            const double mu = qd.dir[static_cast<size_t>(n)].z;
            const double dist = mu > 0 ? z : Z - z;
            exact += qd.weight[static_cast<size_t>(n)] * q * (1.0 - std::exp(-dist / std::abs(mu)));
        }
        // Absolute error relative to the infinite-medium fluence 4π q/kappa: at the boundary
        // cell psi itself is O(h) for the directions leaving the wall, so a pointwise relative
        // error would not shrink there.
        const double e = std::abs(out.fluence(i, j, k) - exact) / (4.0 * std::acos(-1.0) * q);
        err = std::max(err, e);
        if (z > 0.3 * Z && z < 0.7 * Z) interior = std::max(interior, e);
    });
    MPI_Allreduce(MPI_IN_PLACE, &err, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &interior, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    if (interior_error) *interior_error = interior;
    return err;
}

TEST(DomAbsorber, DeepInteriorEqualsInfiniteMediumAnswer) {
    // 120 mean free paths thick: the middle 40% sees 4π q/kappa to round-off (the step
    // scheme keeps the infinite-medium solution exactly; the boundary's influence decays by at
    // least mu/(h kappa + mu) < 1/2 per cell).
    double interior = 0.0;
    absorber_slab_error(120, 120.0, 8, &interior);
    EXPECT_LT(interior, 1e-9);
}

TEST(DomAbsorber, StepSchemeConvergesAtFirstOrder) {
    // tau 1 with S4 (smallest |mu| 0.30): h kappa/|mu| <= 0.2 from nz = 16 on, the asymptotic range.
    const double e16 = absorber_slab_error(16, 1.0, 4), e32 = absorber_slab_error(32, 1.0, 4),
                 e64 = absorber_slab_error(64, 1.0, 4);
    if (test::world_rank() == 0) std::printf("absorber slab tau 1, S4: max rel error nz=16 %.4e, 32 %.4e, 64 %.4e\n", e16, e32, e64);
    EXPECT_LT(e64, 0.05);
    EXPECT_NEAR(std::log2(e16 / e32), 1.0, 0.25);
    EXPECT_NEAR(std::log2(e32 / e64), 1.0, 0.15);
}

TEST(DomModel, EnergyBalanceOfTheSweepIsExact) {
    test::DomWorld w(MPI_COMM_WORLD, {8, 6, 10}, 0.5, BandOptics{"gray", 0.8, 0.9, 0.6});
    for_each_cell(w.d.local(), [&](int i, int j, int k) { w.m.rho(i, j, k) = 0.5 + 0.1 * ((i + 2 * j + k) % 3); });
    // tau_rho: any positive field is a valid first-collision amplitude for this check.
    w.add_sun_from_top({0.3, 0.2, -1.0});
    DomOptions o;
    o.order = 4;
    o.legendre_order = 3;
    o.iteration = "source";
    o.tolerance = 1e-11;
    DiffuseSolution sol;
    make_dom_model(o)->solve(w.ctx(), sol);
    const auto& band = w.report.values()["dom"]["solves"][0];
    if (test::world_rank() == 0)
        std::printf("energy balance %.3e after %d iterations, source power %.4e\n", band["energy_balance"].get<double>(),
                    band["iterations"].get<int>(), band["source_power"].get<double>());
    EXPECT_GT(band["source_power"].get<double>(), 0.0);
    EXPECT_LT(std::abs(band["energy_balance"].get<double>()), 1e-9);
    ASSERT_EQ(sol.fluence.size(), 1u);
    ASSERT_EQ(sol.flux.size(), 1u);
}

}  // namespace
}  // namespace nimbus
