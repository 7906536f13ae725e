// Convergence of the discrete-ordinates model toward the Monte Carlo reference as the angular
// order N grows (issue item 5: "report error against N"), on a small cloud: a smooth blob
// rho = (1 - r²/R²)² (R = 13/32 of the box), sun at an angle (0.5, 0.3, -1), albedo 0.99,
// HG g = 0.85, blob diameter optical thickness ≈ 5 (centre cell 0.75 on 16³, 0.375 on 32³).
// Reference: the Monte Carlo model (solvers/montecarlo), fixed seed (same result on any rank
// count); its noise sqrt(Σ s²) / ||MC||, from the per-cell standard errors s, is printed and
// checked to be well below the DOM errors. Both models get the same exact sun transmittance
// (long characteristics), so the difference is DOM's discretization (angle, delta-M truncation
// at Legendre order L, step scheme in space) plus the MC noise. Metric: relative L2 of
// fluence_diffuse over cells with density (as `nimbus compare`); "minus noise" removes the MC
// noise in quadrature. DOM iterates with DSA-preconditioned GMRES (gmres.h), tolerance 1e-5.
//
// What the measurements show (numbers in solvers/dom/README.md, "Convergence in N"):
// 1. At a fixed L (3, the default), the error decreases from S2 to S4 to S8 and then stays on a
//    floor: S8, S12 and the product set agree within a few per cent of each other.
// 2. The floor is the step scheme's first-order SPATIAL error: halving h divides it by ≈ 1.7.
// 3. With the usual pairing L = N - 1 the error does NOT decrease beyond S4 on these grids: a
//    larger L keeps less of the forward peak in delta-M (f = g^(L+1)), so the scaled problem is
//    optically thicker per cell and more forward-peaked, and the step scheme's spatial error
//    grows; it still falls as h is refined (2.).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "solvers/dom/dom.h"
#include "solvers/light/sun_transmittance.h"
#include "solvers/montecarlo/montecarlo.h"
#include "src/core/halo.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

// The blob on n³ cells; the physical cloud is the same for every n.
struct Cloud {
    Scene scene;
    Decomposition d;
    Medium m;
    LightTransport light;
    Report report;
    explicit Cloud(int n) : d(MPI_COMM_WORLD, {n, n, n}) {
        const double radius = 6.5 * n / 16.0, c = 0.5 * (n - 1);
        scene.grid.n = {n, n, n};
        m.grid.n = {n, n, n};
        m.grid.h = 0.75 * 16.0 / n;  // metres; sigma_t = 1/m at rho = 1
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            const double r2 = (std::pow(i - c, 2) + std::pow(j - c, 2) + std::pow(k - c, 2)) / (radius * radius);
            m.rho(i, j, k) = r2 < 1.0 ? (1.0 - r2) * (1.0 - r2) : 0.0;
        });
        exchange_halo(m.rho, d);
        m.bands = {BandOptics{"gray", 1.0, 0.99, 0.85}};
        const std::vector<DirectionalLight> sun{DirectionalLight{"sun", normalized(Vec3{0.5, 0.3, -1.0}), {1.0}}};
        light = compute_light_transport(d, m, sun, report, {}, LightSpec::Method::exact);
    }
    SolveContext ctx() { return {scene, d, m, light, report}; }
};

struct Reference {
    std::unique_ptr<Cloud> cloud;
    DiffuseSolution mc;
    double noise = 0.0;  // sqrt(Σ s²) / ||MC|| over cells with density
};

struct Measured {
    int directions = 0;
    int iterations = 0;
    double seconds = 0.0;
    double rel_l2 = 0.0;
};

struct DomCase {
    std::string label;
    std::string quadrature;
    int order = 0;  // level-symmetric N, or the product set's polar points
    int azimuthal = 0;
    int legendre_order = 0;
};

class DomConvergence : public ::testing::Test {
protected:
    static constexpr std::int64_t kPhotons = 10'000'000;

    static void TearDownTestSuite() { refs_.clear(); }  // communicators freed before MPI_Finalize

    // The MC reference on n³ (traced once per grid size).
    static Reference& reference(int n) {
        Reference& r = refs_[n];
        if (r.cloud) return r;
        r.cloud = std::make_unique<Cloud>(n);
        MonteCarloOptions o;
        o.photons = kPhotons;
        o.seed = 20261122;
        const double t0 = MPI_Wtime();
        make_montecarlo_model(o)->solve(r.cloud->ctx(), r.mc);
        double s[2] = {0.0, 0.0};
        for_each_cell(r.cloud->d.local(), [&](int i, int j, int k) {
            if (r.cloud->m.rho(i, j, k) <= 0.0) return;
            s[0] += std::pow(r.mc.fluence_stderr[0](i, j, k), 2);
            s[1] += std::pow(r.mc.fluence[0](i, j, k), 2);
        });
        MPI_Allreduce(MPI_IN_PLACE, s, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
        r.noise = std::sqrt(s[0] / s[1]);
        if (test::world_rank() == 0)
            std::printf("Monte Carlo reference, %d³: %lld photons, %.1f s, noise %.2e (rel. L2)\n", n,
                        static_cast<long long>(kPhotons), MPI_Wtime() - t0, r.noise);
        return r;
    }

    // DOM on n³ against the reference (each case solved once per binary run).
    static Measured run_dom(int n, const DomCase& k) {
        const std::string key = std::to_string(n) + "/" + k.label + "/" + std::to_string(k.legendre_order);
        if (auto it = results_.find(key); it != results_.end()) return it->second;
        Reference& ref = reference(n);
        Cloud& c = *ref.cloud;
        DomOptions o;
        o.quadrature = k.quadrature;
        if (k.quadrature == "product") {
            o.polar = k.order;
            o.azimuthal = k.azimuthal;
        } else {
            o.order = k.order;
        }
        o.legendre_order = k.legendre_order;
        o.scheme = "step";
        o.iteration = "gmres";
        o.tolerance = 1e-5;
        DiffuseSolution sol;
        MPI_Barrier(MPI_COMM_WORLD);
        const double t0 = MPI_Wtime();
        make_dom_model(o)->solve(c.ctx(), sol);
        Measured row;
        row.seconds = MPI_Wtime() - t0;
        MPI_Allreduce(MPI_IN_PLACE, &row.seconds, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        const auto& rec = c.report.values()["dom"];
        row.directions = rec["directions"].get<int>();
        row.iterations = rec["solves"][0]["iterations"].get<int>();
        double s[2] = {0.0, 0.0};
        for_each_cell(c.d.local(), [&](int i, int j, int kk) {
            if (c.m.rho(i, j, kk) <= 0.0) return;
            s[0] += std::pow(sol.fluence[0](i, j, kk) - ref.mc.fluence[0](i, j, kk), 2);
            s[1] += std::pow(ref.mc.fluence[0](i, j, kk), 2);
        });
        MPI_Allreduce(MPI_IN_PLACE, s, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
        row.rel_l2 = std::sqrt(s[0] / s[1]);
        results_[key] = row;
        return row;
    }

    // Runs every case on n³ and prints the table.
    static std::vector<Measured> table(int n, const std::vector<DomCase>& cases, const char* title) {
        std::vector<Measured> rows;
        for (const DomCase& k : cases) rows.push_back(run_dom(n, k));
        const double noise = reference(n).noise;
        if (test::world_rank() == 0) {
            std::printf("%s, %d³, %d rank(s); DOM error against Monte Carlo:\n", title, n, test::world_size());
            std::printf("  %-6s %4s %3s %5s %10s %12s %8s\n", "set", "dirs", "L", "iters", "rel L2", "minus noise",
                        "time s");
            for (size_t q = 0; q < cases.size(); ++q) {
                const double e = rows[q].rel_l2;
                std::printf("  %-6s %4d %3d %5d %10.4e %12.4e %8.2f\n", cases[q].label.c_str(), rows[q].directions,
                            cases[q].legendre_order, rows[q].iterations, e,
                            std::sqrt(std::max(0.0, e * e - noise * noise)), rows[q].seconds);
            }
        }
        return rows;
    }

    static inline std::map<int, Reference> refs_;
    static inline std::map<std::string, Measured> results_;
};

TEST_F(DomConvergence, ErrorDecreasesWithNToTheFloorAtFixedLegendreOrder) {
    const std::vector<DomCase> cases = {
        {"S2", "level-symmetric", 2, 0, 3},   {"S4", "level-symmetric", 4, 0, 3},
        {"S8", "level-symmetric", 8, 0, 3},   {"S12", "level-symmetric", 12, 0, 3},
        {"P8x16", "product", 8, 16, 3},
    };
    const std::vector<Measured> r = table(16, cases, "L = 3 (default)");
    // Measured (1e7 photons, 1 and 2 ranks): 11.1, 4.8, 4.5, 4.5, 4.5 %, MC noise 0.5 %
    // (an earlier reference of 2e7 photons: 11.1, 4.9, 4.6, 4.6, 4.6 %, noise 0.35 %).
    EXPECT_LT(3.0 * reference(16).noise, r[2].rel_l2);
    EXPECT_GT(r[0].rel_l2, r[1].rel_l2);
    EXPECT_GT(r[1].rel_l2, r[2].rel_l2);
    for (size_t q = 3; q < r.size(); ++q) EXPECT_NEAR(r[q].rel_l2, r[2].rel_l2, 0.05 * r[2].rel_l2) << cases[q].label;
    EXPECT_LT(r.back().rel_l2, 0.055);
}

TEST_F(DomConvergence, UsualPairingLEqualsNMinusOneIsLimitedBySpace) {
    const std::vector<DomCase> cases = {
        {"S2", "level-symmetric", 2, 0, 1},   {"S4", "level-symmetric", 4, 0, 3},
        {"S8", "level-symmetric", 8, 0, 7},   {"S12", "level-symmetric", 12, 0, 11},
        {"P8x16", "product", 8, 16, 7},
    };
    const std::vector<Measured> r = table(16, cases, "L = N - 1");
    // Measured: 4.9, 4.9, 7.3, 8.7, 7.3 %: not decreasing past S4 (see the file's header).
    for (size_t q = 0; q < r.size(); ++q) EXPECT_LT(r[q].rel_l2, 0.10) << cases[q].label;
    EXPECT_LT(r[1].rel_l2, r[3].rel_l2);  // the floor rises with L on this grid
}

TEST_F(DomConvergence, FloorIsTheFirstOrderSpatialError) {
    const std::vector<DomCase> cases = {{"S8", "level-symmetric", 8, 0, 3}, {"S8", "level-symmetric", 8, 0, 7}};
    const std::vector<Measured> coarse = table(16, cases, "h = 0.75 m (the cases above)");
    const std::vector<Measured> fine = table(32, cases, "h = 0.375 m");
    for (size_t q = 0; q < cases.size(); ++q) {
        const double ratio = coarse[q].rel_l2 / fine[q].rel_l2;
        if (test::world_rank() == 0)
            std::printf("S8 L %d: error ratio h / (h/2) = %.2f\n", cases[q].legendre_order, ratio);
        // Measured 1.66 (L 3) and 1.73 (L 7) with 2e7 photons: first order (2) less the angular part.
        EXPECT_GT(ratio, 1.4) << "L " << cases[q].legendre_order;
    }
}

}  // namespace
}  // namespace nimbus
