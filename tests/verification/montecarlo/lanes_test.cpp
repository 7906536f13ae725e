// The lane kernel (solvers/montecarlo/trace_lanes.h) against the scalar kernel it vectorizes
// (trace_light.h): the same photons must take the same paths, so the collision and segment
// counts agree exactly, and the voxel tallies, the flux accumulators, the energy counters and
// the touched-cell lists agree to round-off. Cases chosen to reach every branch of the lanes: empty-space jumps and
// exits through every face of a sparse medium (live-pixel entry), periodic wraps, roulette
// (low albedo), isotropic (g = 0) and backward scattering, a medium box smaller than the domain
// (exit faces beyond the box), emitted photons, photon ranges not a multiple of the lanes, and
// the empty cells' tallies (a walked grid larger than the entry box).
// Skipped on a CPU without AVX-512 (the run then never uses the lane kernel).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "solvers/montecarlo/emitter.h"
#include "solvers/montecarlo/photon.h"
#include "solvers/montecarlo/trace_lanes.h"
#include "solvers/montecarlo/trace_light.h"
#include "src/core/empty_space.h"
#include "src/core/error.h"
#include "src/model/options.h"

namespace nimbus::mc {
namespace {

struct Medium {
    std::array<int, 3> n;
    std::vector<float> kappa;
};

// Blobs of extinction in empty space (jumps), plus a thin random haze where `haze` > 0.
Medium sparse_medium(const std::array<int, 3>& n, std::uint64_t seed, double haze) {
    std::mt19937_64 gen(seed);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    Medium m{n, std::vector<float>(static_cast<size_t>(n[0]) * n[1] * n[2], 0.0f)};
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i) {
                const double dx = (i - 0.3 * n[0]) / n[0], dy = (j - 0.6 * n[1]) / n[1], dz = (k - 0.5 * n[2]) / n[2];
                const double ex = (i - 0.75 * n[0]) / n[0], ey = (j - 0.25 * n[1]) / n[1];
                float v = 0.0f;
                if (dx * dx + dy * dy + dz * dz < 0.06) v = static_cast<float>(0.4 + 0.8 * U(gen));
                if (ex * ex + ey * ey + dz * dz < 0.02) v = static_cast<float>(2.0 * U(gen));
                if (v == 0.0f && U(gen) < haze) v = static_cast<float>(0.05 * U(gen));
                m.kappa[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] = v;
            }
    return m;
}

struct Traced {
    PathTally tally;
    std::vector<double> voxel_tally;
    std::vector<double> flux;  // the flux accumulators, [cell][4]
    std::set<std::int64_t> lit;
};

// Traces photons [lo, hi) of `term` with one kernel, from zeroed accumulators.
template <class Kernel>
Traced trace(VoxelGrid& vg, const std::array<bool, 3>& periodic, Kernel&& kernel) {
    for (Voxel& v : vg.voxel) v.tally = 0.0;
    Traced r;
    r.flux.assign(4 * vg.voxel.size(), 0.0);
    std::vector<std::int64_t> lit;
    kernel(vg.view(periodic), lit, r.tally, r.flux.data());
    for (const Voxel& v : vg.voxel) r.voxel_tally.push_back(v.tally);
    r.lit.insert(lit.begin(), lit.end());
    return r;
}

void expect_same(const Traced& a, const Traced& b, const char* what) {
    SCOPED_TRACE(what);
    EXPECT_GT(a.tally.collisions, 0);
    EXPECT_EQ(a.tally.collisions, b.tally.collisions);
    EXPECT_EQ(a.tally.segments, b.tally.segments);
    double total = a.tally.absorbed + a.tally.escaped_direct;
    for (const double e : a.tally.escaped_diffuse) total += e;
    const double tol = 1e-12 * total;
    EXPECT_NEAR(a.tally.absorbed, b.tally.absorbed, tol);
    EXPECT_NEAR(a.tally.escaped_direct, b.tally.escaped_direct, tol);
    EXPECT_NEAR(a.tally.roulette_net, b.tally.roulette_net, tol);
    for (int f = 0; f < 6; ++f) EXPECT_NEAR(a.tally.escaped_diffuse[f], b.tally.escaped_diffuse[f], tol) << "face " << f;
    const double peak = *std::max_element(a.voxel_tally.begin(), a.voxel_tally.end());
    EXPECT_GT(peak, 0.0);
    double worst = 0.0;
    for (size_t i = 0; i < a.voxel_tally.size(); ++i) worst = std::max(worst, std::abs(a.voxel_tally[i] - b.voxel_tally[i]));
    EXPECT_LT(worst, 1e-12 * peak);
    // |w len d_a| <= w len: the flux to 1e-12 of the peak track, and not all zero
    double flux_worst = 0.0, flux_peak = 0.0;
    for (size_t i = 0; i < a.flux.size(); ++i) {
        flux_worst = std::max(flux_worst, std::abs(a.flux[i] - b.flux[i]));
        flux_peak = std::max(flux_peak, std::abs(a.flux[i]));
    }
    EXPECT_GT(flux_peak, 0.0);
    EXPECT_LT(flux_worst, 1e-12 * peak);
    EXPECT_EQ(a.lit, b.lit);
}

struct LightCase {
    const char* name;
    std::array<int, 3> n;
    std::array<bool, 3> periodic;
    double haze;
    Vec3 w;
    PhotonOptics optics;
    bool live_pixels;                 // entry on the live pixels only (as trace_forward)
    std::array<int, 3> origin{0, 0, 0}, domain{0, 0, 0};  // a medium box inside a larger domain
};

TEST(LaneKernel, LightPhotonsTakeTheScalarKernelsPaths) {
    if (!lane_kernel_supported()) GTEST_SKIP() << "this CPU has no AVX-512: the lane kernel never runs here";
    const std::vector<LightCase> cases = {
        {"sparse, oblique, live pixels, forward", {17, 13, 11}, {false, false, false}, 0.02,
         normalized(Vec3{0.4, -0.3, -0.8}), {0.9, 0.85, 0.05}, true},
        {"sparse, every axis negative, all pixels, backward", {12, 15, 10}, {false, false, false}, 0.0,
         normalized(Vec3{-0.5, -0.6, -0.3}), {0.95, -0.6, 0.05}, false},
        {"periodic x/y slab at 60 degrees, isotropic, roulette", {6, 5, 9}, {true, true, false}, 0.3,
         normalized(Vec3{std::sin(1.047), 0.2, -std::cos(1.047)}), {0.5, 0.0, 0.2}, false},
        {"box inside a larger domain, straight down", {9, 8, 7}, {false, false, false}, 0.05,
         Vec3{0.0, 0.0, -1.0}, {0.99, 0.7, 0.05}, true, {5, 3, 2}, {20, 15, 12}},
    };
    for (const LightCase& lc : cases) {
        const Medium med = sparse_medium(lc.n, 7, lc.haze);
        VoxelGrid vg = make_voxels(lc.n, med.kappa);
        if (lc.domain[0] > 0) vg.origin = lc.origin, vg.domain = lc.domain;
        // the entry box in domain cells: the walked grid itself (as trace_forward without empty cells)
        EntrySampler entry(vg.origin, {vg.origin[0] + lc.n[0], vg.origin[1] + lc.n[1], vg.origin[2] + lc.n[2]},
                           lc.periodic, lc.w);
        if (lc.live_pixels) {
            const auto nonempty = [&](const std::array<int, 3>& c) {
                return med.kappa[(static_cast<size_t>(c[2]) * lc.n[1] + c[1]) * lc.n[0] + c[0]] > 0.0f;
            };
            entry.restrict_to(surface_cells(lc.n, lc.periodic, nonempty), lc.periodic, lc.w);
        }
        LightTerm term{&entry, lc.w, nullptr, 3, 0.75};
        const std::int64_t lo = 101, hi = 101 + 4003;  // not a multiple of the lanes
        const Traced scalar = trace(vg, lc.periodic, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons(g, lc.optics, term, 42, lo, hi, false, nullptr, lit, t, f);
        });
        const Traced lanes = trace(vg, lc.periodic, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons_lanes(g, lc.optics, term, 42, lo, hi, lit, t, f);
        });
        expect_same(scalar, lanes, lc.name);
        int faces = 0;
        for (int f = 0; f < 6; ++f) faces += scalar.tally.escaped_diffuse[f] > 0;
        EXPECT_GE(faces, lc.periodic[0] ? 2 : 6) << lc.name << ": light left through too few faces";
    }
}

// MonteCarloOptions::empty_cells: the walked grid is the domain, larger than the entry box (the
// bounding box of the medium), and the diffuse flights tally empty cells too, by unit steps.
// The kernels agree with each other, and the paths are those traced without it: the same
// collisions and energy counters, the same tallies in the cells with density.
TEST(LaneKernel, EmptyCellsTakeTheScalarKernelsPaths) {
    if (!lane_kernel_supported()) GTEST_SKIP() << "this CPU has no AVX-512: the lane kernel never runs here";
    const std::array<int, 3> n{18, 15, 12};
    Medium med = sparse_medium(n, 4, 0.03);
    // no medium within 3 cells of the domain's faces (x, y, and z)
    std::array<int, 3> lo = n, hi{0, 0, 0};
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i) {
                float& v = med.kappa[(static_cast<size_t>(k) * n[1] + j) * n[0] + i];
                const std::array<int, 3> c{i, j, k};
                for (int a = 0; a < 3; ++a)
                    if (c[a] < 3 || c[a] >= n[a] - 3) v = 0.0f;
                if (v > 0.0f)
                    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a] + 1);
            }
    ASSERT_LT(lo[0], hi[0]);
    const auto kappa_at = [&](const std::array<int, 3>& c) {
        return med.kappa[(static_cast<size_t>(c[2]) * n[1] + c[1]) * n[0] + c[0]];
    };
    const Vec3 w = normalized(Vec3{0.3, -0.2, -0.9});
    for (const std::array<bool, 3> periodic : {std::array<bool, 3>{false, false, false}, std::array<bool, 3>{true, true, false}}) {
        SCOPED_TRACE(periodic[0] ? "periodic x, y" : "open");
        std::array<int, 3> elo = lo, ehi = hi;  // the entry box: the whole extent along periodic axes
        for (int a = 0; a < 3; ++a)
            if (periodic[a]) elo[a] = 0, ehi[a] = n[a];
        EntrySampler entry(elo, ehi, periodic, w);
        entry.restrict_to(surface_cells({ehi[0] - elo[0], ehi[1] - elo[1], ehi[2] - elo[2]}, periodic,
                                        [&](const std::array<int, 3>& c) {
                                            return kappa_at({c[0] + elo[0], c[1] + elo[1], c[2] + elo[2]}) > 0.0f;
                                        }),
                          periodic, w);
        VoxelGrid vg = make_voxels(n, med.kappa);  // the whole domain
        const PhotonOptics optics{0.95, 0.7, 0.05};
        LightTerm term{&entry, w, nullptr, 4, 1.0};
        const std::int64_t first = 7, last = 7 + 3001;
        const auto scalar_kernel = [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons(g, optics, term, 5, first, last, false, nullptr, lit, t, f);
        };
        const auto lane_kernel = [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons_lanes(g, optics, term, 5, first, last, lit, t, f);
        };
        const Traced jumping = trace(vg, periodic, scalar_kernel);
        term.empty_cells = true;
        const Traced scalar = trace(vg, periodic, scalar_kernel);
        const Traced lanes = trace(vg, periodic, lane_kernel);
        expect_same(scalar, lanes, "empty cells tallied");
        // The same paths as without the empty cells' tallies.
        EXPECT_EQ(scalar.tally.collisions, jumping.tally.collisions);
        EXPECT_GT(scalar.tally.segments, jumping.tally.segments);
        const double tol = 1e-12 * static_cast<double>(last - first);  // of the photons' total weight
        EXPECT_NEAR(scalar.tally.absorbed, jumping.tally.absorbed, tol);
        EXPECT_NEAR(scalar.tally.escaped_direct, jumping.tally.escaped_direct, tol);
        for (int f = 0; f < 6; ++f) EXPECT_NEAR(scalar.tally.escaped_diffuse[f], jumping.tally.escaped_diffuse[f], tol);
        double peak = 0.0, worst = 0.0;
        std::int64_t empty_lit = 0, empty_outside_box = 0;
        const GridView g = vg.view(periodic);
        for (int k = 0; k < n[2]; ++k)
            for (int j = 0; j < n[1]; ++j)
                for (int i = 0; i < n[0]; ++i) {
                    const std::int64_t idx = g.index({i, j, k});
                    const double v = scalar.voxel_tally[static_cast<size_t>(idx)];
                    peak = std::max(peak, v);
                    if (kappa_at({i, j, k}) > 0.0f) {
                        worst = std::max(worst, std::abs(v - jumping.voxel_tally[static_cast<size_t>(idx)]));
                        continue;
                    }
                    EXPECT_EQ(jumping.voxel_tally[static_cast<size_t>(idx)], 0.0);
                    empty_lit += v > 0.0;
                    empty_outside_box += v > 0.0 && (k < lo[2] || k >= hi[2]);
                }
        EXPECT_LT(worst, 1e-12 * peak);
        EXPECT_GT(empty_lit, 500);          // empty cells inside and around the medium
        EXPECT_GT(empty_outside_box, 100);  // and beyond its box, above and below
    }
}

TEST(LaneKernel, EmittedPhotonsTakeTheScalarKernelsPaths) {
    if (!lane_kernel_supported()) GTEST_SKIP() << "this CPU has no AVX-512: the lane kernel never runs here";
    const std::array<int, 3> n{14, 12, 10};
    const Medium med = sparse_medium(n, 3, 0.05);
    VoxelGrid vg = make_voxels(n, med.kappa);
    const VolumeEmitter emitter({1.0}, Box{{2, 3, 2}, {9, 10, 8}},
                                [&](int i, int j, int k) { return med.kappa[(static_cast<size_t>(k) * n[1] + j) * n[0] + i]; },
                                1.0);
    ASSERT_FALSE(emitter.live.empty());
    const PhotonOptics optics{0.9, 0.8, 0.05};
    LightTerm term{nullptr, Vec3{0, 0, -1}, &emitter, 5, 1.0};
    for (const std::array<bool, 3> periodic : {std::array<bool, 3>{false, false, false}, std::array<bool, 3>{true, false, true}}) {
        const Traced scalar = trace(vg, periodic, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons(g, optics, term, 9, 0, 3001, false, nullptr, lit, t, f);
        });
        const Traced lanes = trace(vg, periodic, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons_lanes(g, optics, term, 9, 0, 3001, lit, t, f);
        });
        expect_same(scalar, lanes, periodic[0] ? "periodic x, z" : "open");
        EXPECT_EQ(scalar.tally.escaped_direct, 0.0);  // emitted light is diffuse from its start
    }
}

// Fewer photons than lanes, and none.
TEST(LaneKernel, FewPhotons) {
    if (!lane_kernel_supported()) GTEST_SKIP() << "this CPU has no AVX-512: the lane kernel never runs here";
    const std::array<int, 3> n{8, 8, 8};
    const Medium med = sparse_medium(n, 1, 0.5);
    VoxelGrid vg = make_voxels(n, med.kappa);
    const Vec3 w = normalized(Vec3{0.1, 0.2, -1.0});
    const EntrySampler entry({0, 0, 0}, n, {false, false, false}, w);
    const LightTerm term{&entry, w, nullptr, 0, 1.0};
    const PhotonOptics optics{0.999, 0.5, 0.05};
    for (const std::int64_t count : {0, 1, 3, 17}) {
        const Traced scalar = trace(vg, {false, false, false}, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons(g, optics, term, 1, 5, 5 + count, false, nullptr, lit, t, f);
        });
        const Traced lanes = trace(vg, {false, false, false}, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
            trace_photons_lanes(g, optics, term, 1, 5, 5 + count, lit, t, f);
        });
        if (count >= 17) {
            expect_same(scalar, lanes, "17 photons");  // collisions > 0, every tally and counter
            continue;
        }
        EXPECT_EQ(scalar.tally.collisions, lanes.tally.collisions) << count;
        EXPECT_EQ(scalar.tally.segments, lanes.tally.segments) << count;
        EXPECT_NEAR(scalar.tally.escaped_direct, lanes.tally.escaped_direct, 1e-12) << count;
        EXPECT_EQ(scalar.lit, lanes.lit) << count;
    }
}

// A seed and photon indices that use the high key and counter words of Philox (photon index
// crossing 2^32 inside a block of eight started photons).
TEST(LaneKernel, HighSeedAndPhotonIndexWords) {
    if (!lane_kernel_supported()) GTEST_SKIP() << "this CPU has no AVX-512: the lane kernel never runs here";
    const std::array<int, 3> n{10, 9, 8};
    const Medium med = sparse_medium(n, 5, 0.2);
    VoxelGrid vg = make_voxels(n, med.kappa);
    const Vec3 w = normalized(Vec3{-0.3, 0.2, -0.9});
    const EntrySampler entry({0, 0, 0}, n, {false, false, false}, w);
    const LightTerm term{&entry, w, nullptr, 2, 1.0};
    const PhotonOptics optics{0.95, 0.6, 0.05};
    const std::uint64_t seed = 0x9E3779B97F4A7C15ull;
    const std::int64_t lo = (std::int64_t{1} << 32) - 5, hi = lo + 1203;
    const Traced scalar = trace(vg, {false, false, false}, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
        trace_photons(g, optics, term, seed, lo, hi, false, nullptr, lit, t, f);
    });
    const Traced lanes = trace(vg, {false, false, false}, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
        trace_photons_lanes(g, optics, term, seed, lo, hi, lit, t, f);
    });
    expect_same(scalar, lanes, "seed and photon indices beyond 32 bits");
}

// A range traced in two calls that cut a block of eight photons is the range traced in one:
// no started photon carries over from one call to the next, none is lost.
TEST(LaneKernel, SplitRangeEqualsWholeRange) {
    if (!lane_kernel_supported()) GTEST_SKIP() << "this CPU has no AVX-512: the lane kernel never runs here";
    const std::array<int, 3> n{8, 8, 8};
    const Medium med = sparse_medium(n, 2, 0.3);
    VoxelGrid vg = make_voxels(n, med.kappa);
    const Vec3 w = normalized(Vec3{0.2, 0.1, -1.0});
    const EntrySampler entry({0, 0, 0}, n, {false, false, false}, w);
    const LightTerm term{&entry, w, nullptr, 1, 1.0};
    const PhotonOptics optics{0.99, 0.85, 0.05};
    const std::int64_t lo = 40, cut = lo + 13, hi = lo + 517;
    const Traced whole = trace(vg, {false, false, false}, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
        trace_photons_lanes(g, optics, term, 3, lo, hi, lit, t, f);
    });
    const Traced split = trace(vg, {false, false, false}, [&](const GridView& g, std::vector<std::int64_t>& lit, PathTally& t, double* f) {
        trace_photons_lanes(g, optics, term, 3, lo, cut, lit, t, f);
        trace_photons_lanes(g, optics, term, 3, cut, hi, lit, t, f);
    });
    expect_same(whole, split, "[lo, cut) + [cut, hi) against [lo, hi)");
}

TEST(LaneKernel, OptionIsChecked) {
    MonteCarloOptions o;
    for (const char* k : {"auto", "lanes", "scalar"}) {
        o.kernel = k;
        EXPECT_NO_THROW(o.validate()) << k;
    }
    o.kernel = "avx";
    EXPECT_THROW(o.validate(), Error);
}

}  // namespace
}  // namespace nimbus::mc
