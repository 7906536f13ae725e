// LPM against the independent 1-D slab reference (tests/support/slab_reference.h): a
// homogeneous slab, periodic in x and y, lit from above; reflection R, diffuse transmission T
// and the interior fluence profile, with exact energy bookkeeping. Each rank solves the thin
// periodic column on MPI_COMM_SELF: its X/Y maps cycle around the 2-cell period hundreds of
// steps, and a message per step on an oversubscribed machine would dominate the test time;
// decomposition invariance, periodic case included, is tested in hard_cases_test.cpp.
#include <gtest/gtest.h>

#include <cmath>

#include "tests/support/mpi_test.h"
#include "tests/support/slab_reference.h"
#include "tests/verification/lpm/lpm_world.h"

namespace nimbus {
namespace {

using test::LpmWorld;
using test::lpm_options;

DirectionalLight beam(double mu0) { return {"sun", {std::sqrt(1.0 - mu0 * mu0), 0.0, -mu0}, {1.0}}; }

struct SlabErrors {
    double R, T, R_ref, T_ref, profile_rel_l2, profile_rel_max;
};

// nz cells over optical thickness tau0, nxy x nxy periodic columns.
SlabErrors run_slab(double tau0, double albedo, double g, double mu0, const LpmOptions& o, int nz = 16, int nxy = 2) {
    LpmWorld w(MPI_COMM_SELF, {nxy, nxy, nz}, {true, true, false}, [](int, int, int) { return 1.0; },
               BandOptics{"gray", tau0 / nz, albedo, g}, {beam(mu0)});
    const lpm::BandResult r = w.solve(o);
    const double incident = mu0 * nxy * nxy;  // E0 mu0 x top area
    test::SlabProblem sp{tau0, albedo, g, mu0};
    sp.profile_levels = 2 * nz;
    const test::SlabSolution ref = test::solve_slab(sp);
    double e2 = 0.0, r2 = 0.0, emax = 0.0, rmax = 0.0;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        const size_t l = static_cast<size_t>(2 * (nz - 1 - k));
        const double expect = (ref.fluence[l] + 4.0 * ref.fluence[l + 1] + ref.fluence[l + 2]) / 6.0;
        const double e = r.fluence(i, j, k) - expect;
        e2 += e * e;
        r2 += expect * expect;
        emax = std::max(emax, std::abs(e));
        rmax = std::max(rmax, expect);
    });
    double s[2] = {e2, r2}, mx[2] = {emax, rmax};
    MPI_Allreduce(MPI_IN_PLACE, s, 2, MPI_DOUBLE, MPI_SUM, w.d.comm());
    MPI_Allreduce(MPI_IN_PLACE, mx, 2, MPI_DOUBLE, MPI_MAX, w.d.comm());
    // Bookkeeping closes exactly, whatever the accuracy.
    EXPECT_NEAR(r.escaped + r.absorbed + r.remaining + r.truncated, r.source, 1e-11 * r.source);
    return {r.escaped_face[2][1] / incident, r.escaped_face[2][0] / incident, ref.reflected, ref.transmitted_diffuse,
            std::sqrt(s[0] / s[1]), mx[0] / mx[1]};
}

void print(const char* what, const SlabErrors& e) {
    if (test::world_rank() == 0)
        std::printf("    %s: R %.5f (ref %.5f, %+.2f%%)  T %.5f (ref %.5f, %+.2f%%)  fluence rel L2 %.4f max %.4f\n", what,
                    e.R, e.R_ref, 100 * (e.R / e.R_ref - 1), e.T, e.T_ref, 100 * (e.T / e.T_ref - 1), e.profile_rel_l2,
                    e.profile_rel_max);
}

// Isotropic, tau 1, albedo 0.9, sun overhead and at 60°. Errors come from the map quadrature
// (p x p directions per face, uniform on the cube face) and the cell-constant U; measured:
// R and T within 0.5% (-0.35%/-0.02% overhead, -0.49%/+0.17% at 60°), the profile within 2%
// (relative L2: 1.6%/2.0%) at p = 9, against 3% and 12-15% at p = 3: the error falls about as
// 1/p² (a midpoint rule on the cube face), so p = 9 must be at least 5x better than p = 3.
// The tolerances were set at 2-2.5x the errors measured before the periodic fix (map_sweep.cpp,
// sweep_lateral), which the 2-cell period (not a multiple of p) had shifted: -0.15%/+0.11%,
// -0.26%/+0.25%, profile 1.3%/1.4%. The values above are what a 9 x 9 or 18 x 18 column gives,
// before the fix and after it, to the digits printed; so R at 60° now has a 1.2x margin (the
// solve is deterministic).
TEST(LpmSlab, IsotropicAgainstReference) {
    for (double mu0 : {1.0, 0.5}) {
        SlabErrors worst{};
        for (int p : {3, 9}) {
            const SlabErrors e = run_slab(1.0, 0.9, 0.0, mu0, lpm_options(p, 1, 8, 1e-4));
            print(p == 3 ? "iso p 3" : "iso p 9", e);
            if (p == 9) {
                EXPECT_NEAR(e.R, e.R_ref, 0.006 * e.R_ref);
                EXPECT_NEAR(e.T, e.T_ref, 0.006 * e.T_ref);
                EXPECT_LT(e.profile_rel_l2, 0.03);
                EXPECT_LT(e.profile_rel_l2, worst.profile_rel_l2 / 5.0);
            }
            worst = e;
        }
    }
}

// HG g = 0.85, tau 1, albedo 0.9, sun overhead: the coarse bins of U must resolve the lobe
// (Fattal Fig. 6). k = 1 (6 bins) is far off (R +112%, T -9%: U cannot hold a forward lobe);
// k = 3 (54 bins, the paper's choice) with 9 x 9 maps: measured R +10% (R is small, 0.03, and
// set by the back lobe, which 54 bins resolve worst: the form factors' mean cosine is off by
// 0.05 at k = 3, angular test), T -1.3%, profile 4.3% (R +10.7%, profile 3.7% before the
// periodic fix, on this 2-cell period). Tolerances: 15%, 2%, 6%.
TEST(LpmSlab, ForwardScatteringAgainstReference) {
    for (int k : {3}) {
        const SlabErrors e = run_slab(1.0, 0.9, 0.85, 1.0, lpm_options(9, k, 8, 1e-4));
        print("g 0.85 p 9 k 3", e);
        {
            EXPECT_NEAR(e.R, e.R_ref, 0.15 * e.R_ref);
            EXPECT_NEAR(e.T, e.T_ref, 0.02 * e.T_ref);
            EXPECT_LT(e.profile_rel_l2, 0.06);
        }
    }
}

// A thin periodic layer between vacuum (tau 0.25 in 4 of 8 cells, 8 x 8 periodic columns,
// albedo 0.9, isotropic, sun overhead): the mean fluence in the layer over the reference's.
double thin_layer_fluence_ratio(int p) {
    const int nz = 8, lo = 2, hi = 6;
    const double tau0 = 0.25;
    LpmWorld w(MPI_COMM_SELF, {8, 8, nz}, {true, true, false}, [&](int, int, int k) { return k >= lo && k < hi ? 1.0 : 0.0; },
               BandOptics{"gray", tau0 / (hi - lo), 0.9, 0.0}, {beam(1.0)});
    const lpm::BandResult r = w.solve(lpm_options(p, 1, 8, 1e-4));
    test::SlabProblem sp{tau0, 0.9, 0.0, 1.0};
    sp.profile_levels = 2 * (hi - lo);
    const test::SlabSolution ref = test::solve_slab(sp);
    double got = 0.0, want = 0.0;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        if (k < lo || k >= hi) return;
        const size_t l = static_cast<size_t>(2 * (hi - 1 - k));
        want += (ref.fluence[l] + 4.0 * ref.fluence[l + 1] + ref.fluence[l + 2]) / 6.0;
        got += r.fluence(i, j, k);
    });
    return got / want;
}

// With odd p the X and Y maps have a row of exactly horizontal rays that never leave the layer
// and cycle round the periodic axes until their light is deposited: measured 1.60, 1.23, 1.07
// times the reference at p = 3, 5, 9. Even p has no such row; the near-horizontal bins' light
// leaves a little early, so it errs low and converges from below: 0.834, 0.912, 0.949 at p = 4,
// 6, 8 (0.902 at p = 6 before the periodic fix: 8 cells are not a multiple of 6). The default
// p is even and within 12% here (0.91).
TEST(LpmSlab, ThinPeriodicLayerEvenP) {
    double previous = 0.0;
    for (int p : {4, 6, 8}) {
        const double ratio = thin_layer_fluence_ratio(p);
        if (test::world_rank() == 0) std::printf("    thin layer p %d: mean fluence / reference %.4f\n", p, ratio);
        EXPECT_LT(ratio, 1.0) << "p " << p;
        EXPECT_GT(ratio, previous) << "p " << p;  // converges from below
        previous = ratio;
    }
    const int p_default = LpmOptions{}.p;
    EXPECT_EQ(p_default % 2, 0);
    const double ratio = thin_layer_fluence_ratio(p_default);
    EXPECT_NEAR(ratio, 1.0, 0.12) << "default p " << p_default;
}

}  // namespace
}  // namespace nimbus
