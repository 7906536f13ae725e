// Spatial schemes and boundaries of the DOM sweep (solvers/dom/transport_sweep.h, cell_kernel.h):
// - manufactured solution: observed order ~1 for step, ~2 for diamond (N = 8..64);
// - the negative-flux fix-up: plain diamond goes negative in thick cells, the fix-up does not
//   and keeps the energy balance;
// - diamond on the slab against the doubling-adding reference, at least as good as step;
// - 1 vs 2 ranks (diamond; diamond + reflective + sky boundary);
// - DSA with diamond on the tau-100 cube;
// - reflective faces: half slab with a reflective bottom = top half of the doubled slab; a
//   closed reflective box with uniform emission = the infinite-medium answer 4π q/(kappa(1-a));
// - sky as boundary radiance: uncollided sky through a pure absorber against
//   Σ_n w_n L exp(-tau/|mu_n|); a scattering slab, boundary against first-collision sky.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>

#include <cmath>
#include <span>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/band_problem.h"
#include "solvers/dom/dom.h"
#include "solvers/dom/iteration.h"
#include "solvers/dom/transport_sweep.h"
#include "src/core/error.h"
#include "src/physics/lights.h"
#include "tests/support/mpi_test.h"
#include "tests/support/slab_reference.h"
#include "tests/verification/dom/dom_world.h"

namespace nimbus {
namespace {

using dom::SpatialScheme;
constexpr double kPi = std::numbers::pi;

double all_max(double v) {
    MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    return v;
}
double all_min(double v) {
    MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
    return v;
}
double all_sum(double v) {
    MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    return v;
}
const char* name(SpatialScheme s) { return s == SpatialScheme::step ? "step" : "diamond"; }

// ---------------------------------------------------------------------------------------------
// Manufactured solution. Only the directions of octant (+,+,+) carry light:
//   psi_n(x) = f(x) = sin(a x) sin(a y) sin(a z),  a = π/(2 X),  on the cube [0, X]³,
// which vanishes on the inflow faces x = 0, y = 0, z = 0 (vacuum) and grows smoothly to the
// outflow faces. Its source S_n = Ω_n·∇f + kappa f is given through the light-term interface
// of the sweep: 4 terms with amplitudes (kappa f, ∂x f, ∂y f, ∂z f) at the cell centres and
// phase tables (1, Ω_x, Ω_y, Ω_z) on the octant's directions (0 elsewhere). Exact fluence:
// W f(x_c), W = Σ_{n in octant} w_n. Error: relative L2 over the cells.
double manufactured_error(int N, SpatialScheme scheme, std::int64_t* fixups = nullptr) {
    const double X = 1.0, h = X / N, kappa = 1.0, a = kPi / (2.0 * X);
    test::DomWorld w(MPI_COMM_WORLD, {N, N, N}, h, BandOptics{"gray", 1.0, 0.0, 0.0});
    const dom::AngularSet ang = dom::make_angular_set(level_symmetric(4), 0);
    const Box& own = w.d.local();
    Field<double> kap(own, 0, 1, kappa), mom(own, 0, ang.nmom, 0.0), amp(own, 0, 4, 0.0);
    auto f = [&](double x, double y, double z) { return std::sin(a * x) * std::sin(a * y) * std::sin(a * z); };
    for_each_cell(own, [&](int i, int j, int k) {
        const double x = (i + 0.5) * h, y = (j + 0.5) * h, z = (k + 0.5) * h;
        amp(i, j, k, 0) = kappa * f(x, y, z);
        amp(i, j, k, 1) = a * std::cos(a * x) * std::sin(a * y) * std::sin(a * z);
        amp(i, j, k, 2) = a * std::sin(a * x) * std::cos(a * y) * std::sin(a * z);
        amp(i, j, k, 3) = a * std::sin(a * x) * std::sin(a * y) * std::cos(a * z);
    });
    dom::SweepSource src;
    src.kappa = &kap;
    src.moments = std::span<const double>(mom.data(), mom.size());
    src.amp = &amp;
    src.nl = 4;
    const int lit = 7;  // octant (+,+,+)
    double W = 0.0;
    for (int o = 0; o < 8; ++o) {
        const auto& oc = ang.octants[static_cast<size_t>(o)];
        const int nd = oc.size();
        auto& P = src.light_phase[static_cast<size_t>(o)];
        P.assign(static_cast<size_t>(4 * nd), 0.0);
        if (o != lit) continue;
        for (int n = 0; n < nd; ++n) {
            P[static_cast<size_t>(n)] = 1.0;
            for (int c = 0; c < 3; ++c) P[static_cast<size_t>((1 + c) * nd + n)] = oc.dir[static_cast<size_t>(n)][c];
            W += oc.weight[static_cast<size_t>(n)];
        }
    }
    dom::TransportSweeper sweeper(w.d, ang, h, {}, 1e-12, scheme);
    dom::SweepOutput out;
    sweeper.sweep(src, out);
    double e2 = 0.0, r2 = 0.0;
    for_each_cell(own, [&](int i, int j, int k) {
        const double exact = W * f((i + 0.5) * h, (j + 0.5) * h, (k + 0.5) * h);
        e2 += std::pow(out.fluence(i, j, k) - exact, 2);
        r2 += exact * exact;
    });
    if (fixups) *fixups = static_cast<std::int64_t>(all_sum(static_cast<double>(sweeper.timing().fixups)));
    return std::sqrt(all_sum(e2) / all_sum(r2));
}

TEST(DomScheme, ManufacturedSolutionOrder) {
    const int Ns[4] = {8, 16, 32, 64};
    for (SpatialScheme s : {SpatialScheme::step, SpatialScheme::diamond}) {
        double e[4];
        std::int64_t fix = 0, fix_n = 0;
        for (int q = 0; q < 4; ++q) {
            e[q] = manufactured_error(Ns[q], s, &fix_n);
            fix += fix_n;
        }
        double order[3];
        for (int q = 0; q < 3; ++q) order[q] = std::log2(e[q] / e[q + 1]);
        if (test::world_rank() == 0)
            std::printf("manufactured %-7s  rel L2 error N=8 %.3e  16 %.3e  32 %.3e  64 %.3e   order %.3f %.3f %.3f  "
                        "fix-ups %lld\n", name(s), e[0], e[1], e[2], e[3], order[0], order[1], order[2],
                        static_cast<long long>(fix));
        const double want = s == SpatialScheme::step ? 1.0 : 2.0;
        for (int q = 1; q < 3; ++q) {
            EXPECT_GE(order[q], want - 0.2) << name(s) << " N " << Ns[q] << " -> " << Ns[q + 1];
            EXPECT_LE(order[q], want + 0.2) << name(s) << " N " << Ns[q] << " -> " << Ns[q + 1];
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Fix-up. A column (periodic 2 x 2 x 16) of thick cells (kappa h = 4): isotropic emission q in
// the lower half, pure absorber above. Light leaving the emitting layers into the first thick
// absorbing cell makes plain diamond's outgoing face value 2 psi - psi_in negative.
struct FixupRun {
    double min_psi = 0, balance = 0;
    std::int64_t fixups = 0;
};
FixupRun thick_column(bool fixup) {
    const int nz = 16;
    const double h = 4.0, q = 1.0;
    test::DomWorld w(MPI_COMM_WORLD, {2, 2, nz}, h, BandOptics{"gray", 1.0, 0.0, 0.0}, {true, true, false});
    DomOptions o;
    o.order = 8;
    const dom::AngularSet ang = dom::make_angular_set(o);
    dom::BandProblem p = dom::make_band_optics(w.m, 0, w.d.local(), ang, true);
    for_each_cell(w.d.local(), [&](int i, int j, int k) { p.emission(i, j, k) = k < nz / 2 ? q : 0.0; });
    dom::add_light_sources(p, w.d, w.m, w.light, 0, ang);
    dom::TransportSweeper sweeper(w.d, ang, h, {}, 1e-13, SpatialScheme::diamond, {}, fixup);
    dom::SweepOutput out;
    const auto r = dom::iterate_band(w.d, sweeper, ang, p, "source", 1e-12, 5, out, w.report);
    EXPECT_TRUE(r.converged);
    FixupRun f;
    f.min_psi = all_min(out.min_psi);
    f.fixups = static_cast<std::int64_t>(all_sum(static_cast<double>(sweeper.timing().fixups)));
    // Energy balance: emitted = absorbed + leaked (exact for any closure of the cell balance).
    double e[2] = {0.0, 0.0};
    const double vol = h * h * h;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        e[0] += vol * 4.0 * kPi * p.emission(i, j, k);
        e[1] += vol * p.sigma_a(i, j, k) * out.fluence(i, j, k);
    });
    e[0] = all_sum(e[0]);
    e[1] = all_sum(e[1]);
    double leaked = 0.0;
    for (double v : out.leakage) leaked += v;
    f.balance = (e[0] - e[1] - leaked) / e[0];
    return f;
}

TEST(DomScheme, FixupKeepsDiamondNonNegative) {
    const FixupRun plain = thick_column(false), fixed = thick_column(true);
    if (test::world_rank() == 0)
        std::printf("thick column (kappa h = 4): plain diamond min psi %.4e (balance %.1e); with fix-up min psi %.4e, "
                    "%lld fix-ups, balance %.1e\n", plain.min_psi, plain.balance, fixed.min_psi,
                    static_cast<long long>(fixed.fixups), fixed.balance);
    EXPECT_LT(plain.min_psi, -1e-3);
    EXPECT_EQ(plain.fixups, 0);
    EXPECT_GE(fixed.min_psi, 0.0);
    EXPECT_GT(fixed.fixups, 0);
    EXPECT_LT(std::abs(fixed.balance), 1e-12);
    EXPECT_LT(std::abs(plain.balance), 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Slab (periodic 4 x 4 x nz, tau 1, albedo 0.9, mu0 0.8, isotropic) against the doubling-adding
// reference: R, T and the fluence at the cell centres. The quadrature is the product set with 32
// Gauss polar points (angular error far below the spatial one): with S16 (fluence error floor
// ~2e-2 from the angles) step's first-order spatial error happens to cancel part of the angular
// one at nz 32-64 and the comparison would say nothing about the schemes.
struct SlabErrors {
    double R = 0, T = 0, fluence = 0;
};
SlabErrors slab(SpatialScheme scheme, int nz, int polar) {
    const double tau0 = 1.0, a = 0.9, mu0 = 0.8, h = tau0 / nz;
    test::DomWorld w(MPI_COMM_WORLD, {4, 4, nz}, h, BandOptics{"gray", 1.0, a, 0.0}, {true, true, false});
    w.add_sun_from_top({0.6, 0.0, -mu0});
    DomOptions o;
    o.quadrature = "product";
    o.polar = polar;
    o.azimuthal = 4;
    o.legendre_order = 0;
    o.iteration = "dsa";
    o.tolerance = 1e-10;
    o.scheme = name(scheme);
    DiffuseSolution sol;
    make_dom_model(o)->solve(w.ctx(), sol);
    const auto leak = w.report.values()["dom"]["solves"][0]["leakage"].get<std::vector<double>>();
    const double incident = mu0 * 16.0 * h * h;
    test::SlabProblem sp;
    sp.tau0 = tau0;
    sp.albedo = a;
    sp.g = 0.0;
    sp.mu0 = mu0;
    sp.profile_levels = 2 * nz;
    const test::SlabSolution ref = test::solve_slab(sp);
    SlabErrors e;
    e.R = leak[5] / incident - ref.reflected;
    e.T = leak[4] / incident - ref.transmitted_diffuse;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        const int level = 2 * (nz - 1 - k) + 1;
        const double d = (sol.fluence[0](i, j, k) - ref.fluence[static_cast<size_t>(level)]) / mu0;
        e.fluence = std::max(e.fluence, std::abs(d));
    });
    e.fluence = all_max(e.fluence);
    return e;
}

// Both schemes against the reference, and diamond at least as close as step. Measured (nz 8,
// 16): step R -4.4e-3, -2.1e-3, T +7.0e-4, +2.9e-4, fluence 9.3e-2, 5.9e-2; diamond R -2.4e-4,
// +1.5e-5, T +5.1e-4, +1.2e-4, fluence 3.1e-2, 1.9e-2 (of the incident flux). Bounds: about
// twice the coarser grid's errors, and both errors fall with nz.
TEST(DomScheme, DiamondSlabMatchesReferenceAtLeastAsWellAsStep) {
    SlabErrors prev_s, prev_d;
    for (int nz : {8, 16}) {
        const SlabErrors s = slab(SpatialScheme::step, nz, 32), dd = slab(SpatialScheme::diamond, nz, 32);
        if (test::world_rank() == 0)
            std::printf("slab tau 1 a 0.9 product 32x4 nz %d: step R %+.2e T %+.2e fluence %.2e | diamond R %+.2e T %+.2e "
                        "fluence %.2e\n", nz, s.R, s.T, s.fluence, dd.R, dd.T, dd.fluence);
        EXPECT_LE(dd.fluence, s.fluence);
        EXPECT_LE(std::abs(dd.R), std::abs(s.R));
        EXPECT_LE(std::abs(dd.T), std::abs(s.T));
        EXPECT_LT(std::abs(s.R), 1e-2);
        EXPECT_LT(std::abs(s.T), 1.5e-3);
        EXPECT_LT(s.fluence, 0.2);
        EXPECT_LT(std::abs(dd.R), 5e-4);
        EXPECT_LT(std::abs(dd.T), 1e-3);
        EXPECT_LT(dd.fluence, 0.06);
        if (nz == 16) {
            EXPECT_LT(s.fluence, prev_s.fluence);
            EXPECT_LT(dd.fluence, prev_d.fluence);
        }
        prev_s = s, prev_d = dd;
    }
}

// ---------------------------------------------------------------------------------------------
// 1 vs 2 ranks: a lumpy cloud lit from the top, solved on the world communicator and on
// MPI_COMM_SELF. Variant 2 adds reflective z- and x+ faces and the sky as boundary radiance.
test::DomWorld cloud(MPI_Comm comm, double sky) {
    const Int3 n{10, 8, 12};
    test::DomWorld w(comm, n, 0.5, BandOptics{"gray", 1.0, 0.95, 0.6});
    auto rho = [](int i, int j, int k) {
        const double r2 = std::pow(i - 4.5, 2) + std::pow(j - 3.5, 2) + std::pow(k - 5.5, 2);
        return r2 < 20 ? 2.0 + 0.3 * ((i + 2 * j + 3 * k) % 4) : 0.0;
    };
    for_each_cell(w.d.local(), [&](int i, int j, int k) { w.m.rho(i, j, k) = rho(i, j, k); });
    w.add_sun_from_top({0.0, 0.0, -1.0});
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        double t = 0.5 * rho(i, j, k);
        for (int kk = k + 1; kk < n[2]; ++kk) t += rho(i, j, kk);
        w.light.tau_rho[0](i, j, k) = t * w.m.grid.h;
    });
    if (sky > 0) w.scene.sky.radiance = {sky};
    return w;
}

double rank_difference(DomOptions o, double sky) {
    test::DomWorld world = cloud(MPI_COMM_WORLD, sky), self = cloud(MPI_COMM_SELF, sky);
    DiffuseSolution a, b;
    make_dom_model(o)->solve(world.ctx(), a);
    make_dom_model(o)->solve(self.ctx(), b);
    const auto [diff, peak] = test::solution_difference(world.d, a, b);
    if (test::world_rank() == 0)
        std::printf("1 vs %d ranks, diamond%s: max diff %.3e of peak %.4f (%d iterations)\n", test::world_size(),
                    sky > 0 ? " + reflective z-, x+ + sky boundary" : "", diff, peak,
                    world.report.values()["dom"]["solves"][0]["iterations"].get<int>());
    EXPECT_GT(peak, 0.0);
    return diff / peak;
}

TEST(DomScheme, DiamondOneAndTwoRanksAgree) {
    DomOptions o;
    o.order = 4;
    o.legendre_order = 3;
    o.tolerance = 1e-11;
    o.tile_rows = 3;
    o.scheme = "diamond";
    o.iteration = "dsa";
    EXPECT_LE(rank_difference(o, 0.0), 1e-9);
    o.reflective = {"z-", "x+"};
    o.sky = "boundary";
    EXPECT_LE(rank_difference(o, 0.2), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// DSA with the diamond scheme on the cube of 12³ cells (16³ for the numbers in this comment), optical thickness tau per axis, albedo
// 0.999, S4, isotropic. dsa.h's D = 1/(3 kappa_tr) + h/4 is the step scheme's diffusion limit:
// with diamond DSA slows down with the cell thickness and diverges from kappa h ~ 2 (measured
// on this cube: 11, 15, 34 iterations at kappa h = 0.5, 1, 1.5; a change of ~1.3 per iteration
// at 2 and 6.25), so the model refuses diamond + dsa on such cells with an Error naming the
// fix: DSA-preconditioned GMRES, which converges (7 .. 26 iterations over the same range).
// A larger numerical-diffusion term does not rescue plain DSA (12³ cube, kappa h 6.25,
// D = 1/(3 kappa_tr) + c h): c = 1/2 still diverges, c = 1 converges at ~0.88 per iteration
// (hundreds of iterations) and slows the step scheme 7 -> 26 and diamond at kappa h = 1 15 -> 30.
using test::CubeRun;
CubeRun thick_cube(double tau, const std::string& scheme, const std::string& method, int max_iterations) {
    const int n = 12;
    const CubeRun r = test::solve_thick_cube(n, tau, 0.999, scheme, method, max_iterations);
    if (test::world_rank() == 0) {
        std::printf("cube tau %.0f (kappa h %.2f), a 0.999, %s + %s: %s after %d iterations%s\n", tau, tau / n,
                    scheme.c_str(), method.c_str(), r.converged ? "converged" : "NOT converged", r.iterations,
                    r.error.empty() ? "" : (" -- " + r.error).c_str());
    }
    return r;
}

TEST(DomScheme, DsaWithDiamondOnTheThickCube) {
    const CubeRun step = thick_cube(75.0, "step", "dsa", 30);
    EXPECT_TRUE(step.converged);
    EXPECT_LE(step.iterations, 10);
    // Moderate cells: DSA works with diamond.
    const CubeRun thin = thick_cube(12.0, "diamond", "dsa", 30);
    EXPECT_TRUE(thin.converged);
    EXPECT_LE(thin.iterations, 20);
    // Thick cells: refused with a clear error, and the alternative converges.
    const CubeRun refused = thick_cube(75.0, "diamond", "dsa", 30);
    EXPECT_FALSE(refused.converged);
    EXPECT_NE(refused.error.find("iteration = 'gmres'"), std::string::npos) << refused.error;
    const CubeRun gmres = thick_cube(75.0, "diamond", "gmres", 60);
    EXPECT_TRUE(gmres.converged);
    EXPECT_LE(gmres.iterations, 30);
}

// ---------------------------------------------------------------------------------------------
// Reflective faces. Periodic 4 x 4 columns; uniform isotropic emission q (W/m³/sr) in an
// absorbing-scattering medium.
struct ColumnRun {
    Field<double> fluence;
    int iterations = 0;
    bool converged = false;
};
ColumnRun emitting_column(int nz, double h, double albedo, const dom::SweepBoundary& bc, SpatialScheme s,
                          const char* method, double tol, std::array<bool, 3> periodic = {true, true, false},
                          Int3 n_xy = {4, 4, 0}) {
    test::DomWorld w(MPI_COMM_WORLD, {n_xy[0], n_xy[1], nz}, h, BandOptics{"gray", 1.0, albedo, 0.0}, periodic);
    const dom::AngularSet ang = dom::make_angular_set(level_symmetric(6), 0);
    dom::BandProblem p = dom::make_band_optics(w.m, 0, w.d.local(), ang, true);
    p.emission.fill(1.0);
    dom::add_light_sources(p, w.d, w.m, w.light, 0, ang);
    dom::TransportSweeper sweeper(w.d, ang, h, {}, 1e-13, s, bc);
    dom::SweepOutput out;
    const auto r = dom::iterate_band(w.d, sweeper, ang, p, method, tol, 2000, out, w.report);
    ColumnRun c;
    c.fluence = out.fluence;
    c.iterations = r.iterations;
    c.converged = r.converged;
    return c;
}

// Half slab [0, Z] with a reflective bottom = top half of the slab [-Z, Z] with vacuum on both
// sides (mirror symmetry of the discrete problem: equal to the iteration tolerance), in about
// as many DSA iterations.
TEST(DomBoundary, ReflectiveBottomEqualsDoubledSlab) {
    const int nz = 12;
    const double h = 0.25, albedo = 0.9;
    dom::SweepBoundary refl;
    refl.reflective[4] = true;  // z-
    for (SpatialScheme s : {SpatialScheme::step, SpatialScheme::diamond}) {
        for (const char* method : {"dsa"}) {
            const ColumnRun half = emitting_column(nz, h, albedo, refl, s, method, 1e-11);
            const ColumnRun full = emitting_column(2 * nz, h, albedo, {}, s, method, 1e-11);
            // Compare on rank-independent values: gather the column profiles.
            std::vector<double> fh(static_cast<size_t>(nz), 0.0), ff(static_cast<size_t>(2 * nz), 0.0);
            for_each_cell(half.fluence.owned(), [&](int i, int j, int k) {
                if (i == 0 && j == 0) fh[static_cast<size_t>(k)] = half.fluence(i, j, k);
            });
            for_each_cell(full.fluence.owned(), [&](int i, int j, int k) {
                if (i == 0 && j == 0) ff[static_cast<size_t>(k)] = full.fluence(i, j, k);
            });
            MPI_Allreduce(MPI_IN_PLACE, fh.data(), nz, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
            MPI_Allreduce(MPI_IN_PLACE, ff.data(), 2 * nz, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
            double diff = 0.0, peak = 0.0;
            for (int k = 0; k < nz; ++k) {
                diff = std::max(diff, std::abs(fh[static_cast<size_t>(k)] - ff[static_cast<size_t>(nz + k)]));
                peak = std::max(peak, ff[static_cast<size_t>(nz + k)]);
            }
            if (test::world_rank() == 0)
                std::printf("reflective bottom vs doubled slab, %s, %s: max rel diff %.2e (%d / %d iterations)\n", name(s),
                            method, diff / peak, half.iterations, full.iterations);
            EXPECT_TRUE(half.converged && full.converged) << name(s) << " " << method;
            EXPECT_LT(diff / peak, 1e-8) << name(s) << " " << method;
            // DSA's zero current on the mirror makes the half slab converge like the doubled
            // one (15 / 15 iterations; 37-38 / 15 with a Marshak condition on the mirror).
            EXPECT_LE(half.iterations, full.iterations + 2) << name(s) << " " << method;
        }
    }
}

// A closed box (all six faces reflective) with uniform emission: the infinite medium,
// fluence = 4π q / (kappa (1 - a)) everywhere. High faces are lagged one sweep: the source
// (and DSA) iteration converges them (DSA's boundary conditions: ClosedReflectiveBoxDsaConverges).
TEST(DomBoundary, ClosedReflectiveBoxIsTheInfiniteMedium) {
    dom::SweepBoundary all;
    all.reflective.fill(true);
    const double q = 1.0, kappa = 1.0;
    const double albedo = 0.5;
    for (SpatialScheme s : {SpatialScheme::step, SpatialScheme::diamond}) {
        for (const char* method : {"source", "dsa"}) {
            {
                const ColumnRun c = emitting_column(4, 0.5, albedo, all, s, method, 1e-12, {false, false, false}, {4, 4, 0});
                const double exact = 4.0 * kPi * q / (kappa * (1.0 - albedo));
                double err = 0.0;
                for_each_cell(c.fluence.owned(), [&](int i, int j, int k) {
                    err = std::max(err, std::abs(c.fluence(i, j, k) / exact - 1.0));
                });
                err = all_max(err);
                if (test::world_rank() == 0)
                    std::printf("closed reflective box, %s, %s, albedo %.2f: max rel error %.2e after %d iterations\n",
                                name(s), method, albedo, err, c.iterations);
                EXPECT_TRUE(c.converged) << name(s) << " " << method << " " << albedo;
                EXPECT_LT(err, 1e-9) << name(s) << " " << method << " " << albedo;
            }
        }
    }
}

// Nearly conservative scattering in the closed reflective box, 4 x 4 x 6 cells of 1 mean free
// path. DSA's diffusion correction has zero current on the mirror faces, and on the high ones
// (reflected one sweep late) the change of the sweep's outgoing current as a boundary source
// (dsa.h). Measured iterations at albedo 0.8 / 0.99: step 14 / 16, diamond 72 / 72; with Marshak
// on every mirror face they were 51 / 697 and 58 / 700, with zero current on the low faces
// only 47 / 524 and 54 / 530, and zero current on the high faces without the source diverged.
// Every run must converge to the infinite-medium answer, in at most 30 (step) or 100 (diamond).
TEST(DomBoundary, ClosedReflectiveBoxDsaConverges) {
    dom::SweepBoundary all;
    all.reflective.fill(true);
    for (double albedo : {0.8, 0.99})
        for (SpatialScheme s : {SpatialScheme::step, SpatialScheme::diamond}) {
            const double exact = 4.0 * kPi / (1.0 - albedo);
            const ColumnRun c = emitting_column(6, 1.0, albedo, all, s, "dsa", 1e-8, {false, false, false}, {4, 4, 0});
            double err = 0.0;
            for_each_cell(c.fluence.owned(), [&](int i, int j, int k) {
                err = std::max(err, std::abs(c.fluence(i, j, k) / exact - 1.0));
            });
            err = all_max(err);
            if (test::world_rank() == 0)
                std::printf("closed reflective box, %s, dsa, albedo %.2f: %d iterations, max rel error %.2e\n", name(s),
                            albedo, c.iterations, err);
            EXPECT_TRUE(c.converged) << name(s) << " " << albedo;
            EXPECT_LT(err, 1e-5) << name(s) << " " << albedo;
            EXPECT_LE(c.iterations, s == SpatialScheme::step ? 30 : 100) << name(s) << " " << albedo;
        }
}

TEST(DomBoundary, ReflectiveOnAPeriodicAxisIsAnError) {
    test::DomWorld w(MPI_COMM_WORLD, {4, 4, 4}, 1.0, BandOptics{"gray", 1.0, 0.5, 0.0}, {true, true, false});
    const dom::AngularSet ang = dom::make_angular_set(level_symmetric(4), 0);
    dom::SweepBoundary bc;
    bc.reflective[1] = true;  // x+
    EXPECT_THROW(dom::TransportSweeper(w.d, ang, 1.0, {}, 1e-10, SpatialScheme::step, bc), Error);
    DomOptions o;
    o.reflective = {"z-", "q+"};
    EXPECT_THROW(o.validate(), Error);
    o.reflective = {"z+"};
    o.iteration = "gmres";
    EXPECT_THROW(o.validate(), Error);
}

// Periodic x/y: each z layer of each octant is swept until its periodic ghosts agree with its
// edges (transport_sweep.cpp). On a slab with empty layers under and over it (as scenes/slab.toml)
// two things made that slow. Where a layer's answer is 0 (upward directions under the slab) the
// ghosts started from another octant's values, and a test relative to the last pass's edge
// values never passed before underflow (~185 passes); and every layer started from such values.
// Extra passes per layer here (source iteration, 26-27 iterations), step / diamond: 73 / (not run) before,
// 7.9 / 28.5 with the test relative to the layer's largest edge value, 3.6 / 12.8 with each
// octant's planes kept from its previous sweep as the start, 3.6 / 5.7 with diamond's ghosts
// from Anderson acceleration instead of steps halfway to the edges.
TEST(DomBoundary, PeriodicLayersConvergeInFewPassesWhereTheLightIsZero) {
    const int nz = 32;
    for (const char* scheme : {"step", "diamond"}) {
        test::DomWorld w(MPI_COMM_WORLD, {8, 8, nz}, 1.0, BandOptics{"gray", 0.1, 0.9, 0.5}, {true, true, false});
        for_each_cell(w.d.local(), [&](int i, int j, int k) { w.m.rho(i, j, k) = (k >= nz / 4 && k < 3 * nz / 4) ? 1.0 : 0.0; });
        w.add_sun_from_top({0.3, 0.2, -0.9});  // tau from the domain top: only a source here
        DomOptions o;
        o.scheme = scheme;
        o.iteration = "source";
        o.tolerance = 1e-6;
        DiffuseSolution sol;
        make_dom_model(o)->solve(w.ctx(), sol);
        const auto& rec = w.report.values()["dom"];
        const auto& band = rec["solves"][0];
        const int iterations = band["iterations"].get<int>();
        // Layer solves: 8 octants x nz layers per sweep, one sweep per source iteration (the
        // report's count is this rank's).
        double passes = rec["periodic_passes"].get<double>();
        MPI_Allreduce(MPI_IN_PLACE, &passes, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
        const double passes_per_layer = passes / (8.0 * nz * iterations);
        if (test::world_rank() == 0)
            std::printf("periodic slab, %s: %d iterations, %.2f extra passes per layer, energy balance %.1e\n", scheme,
                        iterations, passes_per_layer, band["energy_balance"].get<double>());
        EXPECT_TRUE(band["converged"].get<bool>()) << scheme;
        // Light to iterate on (the fixture's tau once gave this slab no source at all: 1
        // iteration, 0 passes, and the test passed without light).
        EXPECT_GT(iterations, 10) << scheme;
        EXPECT_GT(passes_per_layer, 1.0) << scheme;
        EXPECT_LT(passes_per_layer, std::string(scheme) == "step" ? 5.0 : 8.0) << scheme;
        // Stopping the layer iteration early would break the balance of absorbed and leaked light.
        EXPECT_LT(std::abs(band["energy_balance"].get<double>()), 1e-5) << scheme;
    }
}

// GMRES on the same periodic slab: its operator sweeps (Krylov vectors, no external source)
// start their periodic planes from zero, not from the previous vector's, so the operator stays
// linear to the periodic tolerance and the answer agrees with DSA's within the tolerance (1e-4).
// Measured 1.6e-5; with the operator sweeps starting from the last sweep's planes, 1.4e-2 (the
// right-hand side's planes are 1e4 times a unit Krylov vector's here, and the layer test is
// relative to the largest edge value, stale ones included).
// A slab one cell wide along a periodic axis (scenes/slab.toml at 16 x 1 x 64 and 1 x 16 x 64):
// the step scheme's layer iteration contracts slowly there (the ghost feeds the same cell), and
// stopping it at a small change left an error 1/(1 - rho) larger, under which DSA stalled at a
// relative change of 6.7e-4 for 500 iterations (a QA finding); the test is now on the error
// bound (transport_sweep.cpp). Converged in 6 iterations, as at 16 x 16.
TEST(DomBoundary, DsaConvergesOnASlabOneCellWide) {
    for (const Int3 n : {Int3{16, 1, 64}, Int3{1, 16, 64}}) {
        test::DomWorld w(MPI_COMM_WORLD, n, 1.0, BandOptics{"gray", 0.0625, 0.9, 0.5}, {true, true, false});
        for_each_cell(w.d.local(), [&](int i, int j, int k) { w.m.rho(i, j, k) = (k >= 16 && k < 48) ? 1.0 : 0.0; });
        w.add_sun_from_top({0.0, 0.0, -1.0});
        DomOptions o;
        o.max_iterations = 40;
        DiffuseSolution sol;
        EXPECT_NO_THROW(make_dom_model(o)->solve(w.ctx(), sol)) << n[0] << " x " << n[1];
        const auto& solves = w.report.values()["dom"]["solves"];
        ASSERT_FALSE(solves.empty());
        const int iterations = solves[0]["iterations"].get<int>();
        if (test::world_rank() == 0) std::printf("slab %d x %d x 64, step + dsa: %d iterations\n", n[0], n[1], iterations);
        EXPECT_GT(iterations, 3);
        EXPECT_LE(iterations, 12);
    }
}

TEST(DomBoundary, GmresOnAPeriodicSlabAgreesWithDsa) {
    const int nz = 32;
    std::vector<double> fluence[2];
    int n = 0;
    for (const char* method : {"dsa", "gmres"}) {
        test::DomWorld w(MPI_COMM_WORLD, {8, 8, nz}, 1.0, BandOptics{"gray", 0.1, 0.99, 0.5}, {true, true, false});
        for_each_cell(w.d.local(), [&](int i, int j, int k) { w.m.rho(i, j, k) = (k >= nz / 4 && k < 3 * nz / 4) ? 1.0 : 0.0; });
        w.add_sun_from_top({0.3, 0.2, -0.9}, 1e4);
        DomOptions o;
        o.iteration = method;
        o.tolerance = 1e-4;
        DiffuseSolution sol;
        make_dom_model(o)->solve(w.ctx(), sol);
        EXPECT_TRUE(w.report.values()["dom"]["solves"][0]["converged"].get<bool>()) << method;
        EXPECT_GT(w.report.values()["dom"]["solves"][0]["iterations"].get<int>(), 3) << method;  // there is light
        for_each_cell(w.d.local(), [&](int i, int j, int k) { fluence[n].push_back(sol.fluence[0](i, j, k)); });
        ++n;
    }
    double v[2] = {0.0, 0.0};
    for (size_t q = 0; q < fluence[0].size(); ++q) {
        v[0] = std::max(v[0], std::abs(fluence[1][q] - fluence[0][q]));
        v[1] = std::max(v[1], std::abs(fluence[0][q]));
    }
    MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    if (test::world_rank() == 0) std::printf("periodic slab: gmres against dsa, max difference %.2e of max fluence\n", v[0] / v[1]);
    EXPECT_LT(v[0] / v[1], 1e-4);
}

// ---------------------------------------------------------------------------------------------
// Sky radiance as a boundary condition.

// Uncollided sky through a pure absorber slab (periodic 4 x 4 x nz, optical thickness tau0):
// exact on the quadrature, Σ_{mu_n < 0} w_n L exp(-kappa (Z - z)/|mu_n|), at the cell centres.
double absorber_sky_error(SpatialScheme s, int nz) {
    const double tau0 = 2.0, h = tau0 / nz, L = 1.0;
    test::DomWorld w(MPI_COMM_WORLD, {2, 2, nz}, h, BandOptics{"gray", 1.0, 0.0, 0.0}, {true, true, false});
    const dom::AngularSet ang = dom::make_angular_set(level_symmetric(8), 0);
    const Box& own = w.d.local();
    Field<double> kap(own, 0, 1, 1.0), mom(own, 0, ang.nmom, 0.0), amp(own, 0, 1, 0.0);
    dom::SweepSource src;
    src.kappa = &kap;
    src.moments = std::span<const double>(mom.data(), mom.size());
    src.amp = &amp;
    dom::SweepBoundary bc;
    bc.sky = true;
    dom::TransportSweeper sweeper(w.d, ang, h, {}, 1e-10, s, bc);
    sweeper.set_sky_radiance(L);
    dom::SweepOutput out;
    sweeper.sweep(src, out);
    const Quadrature& qd = ang.quadrature;
    double err = 0.0;
    for_each_cell(own, [&](int i, int j, int k) {
        const double depth = tau0 - (k + 0.5) * h;
        double exact = 0.0;
        for (int n = 0; n < qd.size(); ++n) {
            const double mu = qd.dir[static_cast<size_t>(n)].z;
            if (mu < 0) exact += qd.weight[static_cast<size_t>(n)] * L * std::exp(-depth / -mu);
        }
        err += std::pow((out.fluence(i, j, k) - exact) / (2.0 * kPi * L), 2);
    });
    return std::sqrt(all_sum(err) / w.d.global().cells());
}

TEST(DomSky, UncollidedSkyThroughAnAbsorberIsExactOnTheQuadrature) {
    for (SpatialScheme s : {SpatialScheme::step, SpatialScheme::diamond}) {
        const double e16 = absorber_sky_error(s, 16), e32 = absorber_sky_error(s, 32), e64 = absorber_sky_error(s, 64);
        const double order = std::log2(e32 / e64);
        if (test::world_rank() == 0)
            std::printf("sky through absorber tau 2, S8, %s: rms err / (2π L) nz=16 %.3e, 32 %.3e, 64 %.3e (order %.2f "
                        "%.2f)\n", name(s), e16, e32, e64, std::log2(e16 / e32), order);
        const double want = s == SpatialScheme::step ? 1.0 : 2.0;
        EXPECT_NEAR(order, want, 0.2) << name(s);
        EXPECT_LT(e64, s == SpatialScheme::step ? 1e-2 : 3e-4) << name(s);
    }
}

// A slab lit by the sky only (periodic 4 x 4 x nz, tau 1, albedo a): the model's fluence_diffuse
// with sky = "boundary" against sky = "first-collision" (n_sky equal-solid-angle bins).
struct SkySlab {
    std::vector<double> fluence;  // column profile
};
SkySlab sky_slab(const std::string& sky, double albedo, int order, int nz, int bins) {
    const double tau0 = 1.0, h = tau0 / nz, L = 0.5;
    test::DomWorld w(MPI_COMM_WORLD, {4, 4, nz}, h, BandOptics{"gray", 1.0, albedo, 0.0}, {true, true, false});
    w.scene.sky.radiance = {L};
    w.scene.sky.directions = bins;
    // The bins of src/physics/lights.cpp (equal solid angle 2π/n), the sun off.
    w.scene.sun.enabled = false;
    for (const DirectionalLight& bin : make_lights(w.scene)) {
        const double mu = -bin.w.z;
        w.light.lights.push_back(bin);
        Field<double> tau(w.d.local(), 1, 1, 0.0);
        for_each_cell(w.d.local(), [&](int i, int j, int k) { tau(i, j, k) = (nz - k - 0.5) * h / mu; });
        exchange_halo(tau, w.d);  // the light pass's contract
        w.light.tau_rho.push_back(std::move(tau));
    }
    DomOptions o;
    o.order = order;
    o.legendre_order = 0;
    o.iteration = "dsa";
    o.tolerance = 1e-10;
    o.sky = sky;
    DiffuseSolution sol;
    make_dom_model(o)->solve(w.ctx(), sol);
    SkySlab r;
    r.fluence.assign(static_cast<size_t>(nz), 0.0);
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        if (i == 0 && j == 0) r.fluence[static_cast<size_t>(k)] = sol.fluence[0](i, j, k);
    });
    MPI_Allreduce(MPI_IN_PLACE, r.fluence.data(), nz, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    return r;
}

TEST(DomSky, PureAbsorberHasNoDiffuseLightWithBoundarySky) {
    const SkySlab r = sky_slab("boundary", 0.0, 8, 16, 16);
    double m = 0.0;
    for (double v : r.fluence) m = std::max(m, std::abs(v));
    if (test::world_rank() == 0) std::printf("sky boundary, pure absorber: max |fluence_diffuse| %.2e\n", m);
    // fluence_diffuse = the solve's fluence - the uncollided sky's (one more sweep), each with
    // periodic planes converged to 0.1 x tolerance = 1e-11 of the edge radiance (<= L = 0.5) per
    // direction: |difference| <= 2π L 1e-11 = 3.1e-11 (measured 2.0e-12). Until the planes were
    // kept between sweeps (transport_sweep.h) both sweeps started from the values the previous
    // octant left and took the same passes, so they cancelled to round-off (< 1e-13).
    EXPECT_LT(m, 2.0 * kPi * 0.5 * 1e-11);
}

// The same with mirror faces, on a box: a high mirror returns the previous sweep's light, so
// the uncollided sky is swept until its reflections settle. With one sweep the sky that the
// x+ mirror reflected stayed in fluence_diffuse (0.28 of 2πL on a 16³ absorber, a QA finding).
TEST(DomSky, PureAbsorberBetweenMirrorsHasNoDiffuseLightWithBoundarySky) {
    const double L = 0.5;
    for (const std::vector<std::string>& mirrors :
         {std::vector<std::string>{"x+"}, {"x+", "y+", "z-"}, {"x-", "x+"}, {"y-", "y+", "x+"}}) {
        test::DomWorld w(MPI_COMM_WORLD, {8, 6, 10}, 0.1, BandOptics{"gray", 1.0, 0.0, 0.0});
        w.scene.sky.radiance = {L};
        w.scene.sun.enabled = false;
        DomOptions o;
        o.order = 4;
        o.legendre_order = 0;
        o.iteration = "dsa";
        o.tolerance = 1e-10;
        o.sky = "boundary";
        o.reflective = mirrors;
        DiffuseSolution sol;
        make_dom_model(o)->solve(w.ctx(), sol);
        double m = 0.0;
        for_each_cell(w.d.local(), [&](int i, int j, int k) { m = std::max(m, std::abs(sol.fluence[0](i, j, k))); });
        MPI_Allreduce(MPI_IN_PLACE, &m, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        if (test::world_rank() == 0)
            std::printf("sky boundary, pure absorber, mirrors %s: max |fluence_diffuse| %.2e\n",
                        fmt::format("{}", fmt::join(mirrors, " ")).c_str(), m);
        // Both sweeps are exact without scattering (no iteration): round-off of 2πL.
        EXPECT_LT(m, 2.0 * kPi * L * 1e-12) << fmt::format("{}", fmt::join(mirrors, " "));
    }
}

TEST(DomSky, BoundaryAgreesWithFirstCollision) {
    // Both treatments carry an angular discretization error of the sky: the first-collision
    // one integrates the uncollided sky with its n bins (midpoint rule in mu), the boundary one
    // with the S_N directions, then scatters on the S_N quadrature in both. The difference is
    // this ray effect and must shrink as both refine.
    double prev = 0.0;
    const int orders[2] = {4, 12}, bins[2] = {16, 64};
    for (int q = 0; q < 2; ++q) {
        const SkySlab b = sky_slab("boundary", 0.9, orders[q], 16, bins[q]);
        const SkySlab f = sky_slab("first-collision", 0.9, orders[q], 16, bins[q]);
        double diff = 0.0, peak = 0.0;
        for (size_t k = 0; k < b.fluence.size(); ++k) {
            diff = std::max(diff, std::abs(b.fluence[k] - f.fluence[k]));
            peak = std::max(peak, f.fluence[k]);
        }
        if (test::world_rank() == 0)
            std::printf("sky slab tau 1 a 0.9, S%d, %d sky bins: boundary vs first-collision max diff %.3e of peak %.4f "
                        "(%.2f %%)\n", orders[q], bins[q], diff, peak, 100.0 * diff / peak);
        EXPECT_GT(peak, 0.0);
        // Measured (nz 16): 5.6 % (S4, 16 bins), 1.24 % (S12, 64 bins); with the spiral bins used
        // until the thirty-second session (16 and 64 distinct mu for this slab, where the
        // symmetric rings have 4 and 16) 6.1 % and 0.90 %.
        if (q == 0) {
            EXPECT_LT(diff / peak, 0.10);
        } else {
            EXPECT_LT(diff / peak, 0.02);
            EXPECT_LT(diff / peak, 0.25 * prev);
        }
        prev = diff / peak;
    }
}

}  // namespace
}  // namespace nimbus
