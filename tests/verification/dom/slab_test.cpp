// Plane-parallel slab (periodic 4 x 4 x nz) of optical thickness 1, albedo 0.9, lit by a
// collimated beam at mu0 = 0.8: reflection, diffuse transmission and the interior diffuse
// fluence against the independent doubling-adding reference (tests/support/slab_reference.h),
// isotropic and HG g = 0.85 and 0.95 (delta-M). Tolerances are set from the measured discretization
// error (step scheme O(h), angular O(N)); the refinement that reduces them is checked too.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

#include "solvers/dom/dom.h"
#include "tests/support/mpi_test.h"
#include "tests/support/slab_reference.h"
#include "tests/verification/dom/dom_world.h"

namespace nimbus {
namespace {

struct SlabErrors {
    double R = 0, T = 0, R_ref = 0, T_ref = 0;
    double fluence = 0;  // max |fluence - reference| / (E0 mu0) over the cell centres
};

SlabErrors run_slab(double g, int nz, int order, int L, const char* method = "dsa") {
    const double tau0 = 1.0, a = 0.9, mu0 = 0.8, h = tau0 / nz;
    test::DomWorld w(MPI_COMM_WORLD, {4, 4, nz}, h, BandOptics{"gray", 1.0, a, g}, {true, true, false});
    w.add_sun_from_top({0.6, 0.0, -mu0});
    DomOptions o;
    o.order = order;
    o.legendre_order = L;
    o.iteration = method;
    o.tolerance = 1e-9;
    DiffuseSolution sol;
    make_dom_model(o)->solve(w.ctx(), sol);
    const auto& band = w.report.values()["dom"]["solves"][0];
    const auto leak = band["leakage"].get<std::vector<double>>();
    const double f = band["delta_m_f"].get<double>();
    const double area = 16.0 * h * h, incident = mu0 * area;
    // The delta-M forward peak leaves the bottom as scattered (diffuse) light too.
    const double forward_out = (std::exp(-(1.0 - a * f) * tau0 / mu0) - std::exp(-tau0 / mu0)) * mu0 * area;
    SlabErrors e;
    e.R = leak[5] / incident;
    e.T = (leak[4] + forward_out) / incident;
    test::SlabProblem sp;
    sp.tau0 = tau0;
    sp.albedo = a;
    sp.g = g;
    sp.mu0 = mu0;
    sp.profile_levels = 2 * nz;
    // The reference is costly at g = 0.95 (many Legendre terms): solved once per (g, nz).
    static std::map<std::pair<double, int>, test::SlabSolution> cache;
    const auto key = std::make_pair(g, nz);
    if (cache.find(key) == cache.end()) cache.emplace(key, test::solve_slab(sp));
    const test::SlabSolution& ref = cache.at(key);
    e.R_ref = ref.reflected;
    e.T_ref = ref.transmitted_diffuse;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        const int level = 2 * (nz - 1 - k) + 1;  // tau from the top at the cell centre
        const double err = std::abs(sol.fluence[0](i, j, k) - ref.fluence[static_cast<size_t>(level)]) / mu0;
        e.fluence = std::max(e.fluence, err);
    });
    MPI_Allreduce(MPI_IN_PLACE, &e.fluence, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    if (test::world_rank() == 0)
        std::printf("slab g=%.2f nz=%d S%d L=%d: R %.5f (ref %.5f, err %+.2e)  T %.5f (ref %.5f, err %+.2e)  "
                    "fluence max err %.2e, %d iterations\n",
                    g, nz, order, L, e.R, e.R_ref, e.R - e.R_ref, e.T, e.T_ref, e.T - e.T_ref, e.fluence,
                    band["iterations"].get<int>());
    return e;
}

// Measured (nz = 64; the spatial error of the step scheme is then below the angular one):
//   isotropic  S8: R err +1.8e-3, T err +4.1e-4, fluence max err 4.8e-2
//              S16: R err +3.9e-4, T err +2.0e-5, fluence max err 1.8e-2
//   g = 0.85, delta-M  S8 L=7: R err +1.3e-3, T err +7.1e-4, fluence 2.6e-2
//                      S12 L=11: R err +4.5e-4, T err -2.3e-4, fluence 8.1e-3
// The tolerances below are 2-4 times the finer set's error (the solve is deterministic, so
// the margin covers only round-off across rank counts and compilers; T's error is so small
// that its bound is 1e-4); the coarser set must be worse.
TEST(DomSlab, IsotropicMatchesReference) {
    const SlabErrors c = run_slab(0.0, 64, 8, 0), f = run_slab(0.0, 64, 16, 0);
    EXPECT_LT(std::abs(f.R - f.R_ref), 8e-4);
    EXPECT_LT(std::abs(f.T - f.T_ref), 1e-4);
    EXPECT_LT(f.fluence, 0.03);
    EXPECT_LT(f.fluence, 0.5 * c.fluence);
    EXPECT_LT(std::abs(f.R - f.R_ref), std::abs(c.R - c.R_ref));
}

// The hard case g = 0.95 (delta-M keeps f = g^(L+1) in the forward peak: 0.54 at L 11).
// Measured: S8 L=7: R err +1.37e-3, T err +1.0e-4, fluence 2.0e-2 (12 DSA iterations);
//           S12 L=11: R err -1.05e-4, T err -3.6e-5, fluence 8.4e-3 (16 iterations).
TEST(DomSlab, StronglyForwardPeakedHgMatchesReference) {
    const SlabErrors c = run_slab(0.95, 64, 8, 7), f = run_slab(0.95, 64, 12, 11);
    EXPECT_LT(std::abs(f.R - f.R_ref), 3e-4);
    EXPECT_LT(std::abs(f.T - f.T_ref), 1e-4);
    EXPECT_LT(f.fluence, 0.017);
    EXPECT_LT(f.fluence, c.fluence);
}

TEST(DomSlab, ForwardPeakedHgMatchesReference) {
    const SlabErrors c = run_slab(0.85, 64, 8, 7), f = run_slab(0.85, 64, 12, 11);
    EXPECT_LT(std::abs(f.R - f.R_ref), 1e-3);
    EXPECT_LT(std::abs(f.T - f.T_ref), 5e-4);
    EXPECT_LT(f.fluence, 0.015);
    EXPECT_LT(f.fluence, 0.5 * c.fluence);
    EXPECT_LT(std::abs(f.R - f.R_ref), std::abs(c.R - c.R_ref));
}

// Backscattering HG (g < 0) has no forward peak for delta-M to remove (angular_moments.h: f = 0);
// with f = g^{L+1} the scaled chi*_1 left [-1, 1] (g = -0.9, L = 7: -2.3) and DSA diverged.
// Measured (nz = 64):
//   g = -0.5  S8 L=7: R err +8.2e-4, T err +1.1e-3, fluence 4.3e-2 (17 DSA iterations)
//             S12 L=11: R err -7.3e-5, T err +8.4e-4, fluence 2.5e-2 (16)
//   g = -0.9  S8 L=7: R err +1.3e-3, T err +2.6e-3, fluence 5.6e-2 (41)
//             S12 L=11: R err -3.3e-3, T err +5.6e-4, fluence 3.8e-2 (38)
// At g = -0.9 the truncated series is the error (chi_12 = 0.28 is cut off); the tolerances are
// 2-3 times the finer set's error, and the finer set must be better in the fluence.
TEST(DomSlab, BackscatteringHgMatchesReference) {
    struct Case {
        double g, R_tol, T_tol;
    };
    for (const Case& k : {Case{-0.5, 2e-4, 2e-3}, Case{-0.9, 7e-3, 1.2e-3}}) {
        const SlabErrors c = run_slab(k.g, 64, 8, 7), f = run_slab(k.g, 64, 12, 11);
        EXPECT_LT(std::abs(f.R - f.R_ref), k.R_tol) << "g " << k.g;
        EXPECT_LT(std::abs(f.T - f.T_ref), k.T_tol) << "g " << k.g;
        EXPECT_LT(f.fluence, c.fluence) << "g " << k.g;
    }
}

}  // namespace
}  // namespace nimbus
