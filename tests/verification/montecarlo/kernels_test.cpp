// The Monte Carlo inner kernels against independent answers: the azimuth's sincos_2pi against
// libm; the grid walk (padded grid, empty-space skipping, leaving through the ghost layer)
// against chord lengths computed cell by cell by slab clipping; cell_of inverts index; a walk
// on the bounding box of the medium equals the walk on the whole domain (segments, exit face);
// the live-pixel entry mask is conservative: every entry ray that meets a non-empty cell (by
// chord lengths, or by the walk when periodic) starts on a live pixel.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include "src/core/empty_space.h"
#include "src/core/grid_walk.h"
#include "solvers/montecarlo/photon.h"
#include "solvers/montecarlo/sincos.h"

namespace nimbus::mc {
namespace {

TEST(Kernels, SincosMatchesLibm) {
    std::mt19937_64 gen(11);
    std::vector<double> xs{0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0 - 0x1p-33, 0x1p-33};
    for (int i = 0; i < 200000; ++i) xs.push_back((static_cast<double>(gen() >> 32) + 0.5) * 0x1p-32);
    double worst = 0.0;
    for (const double xi : xs) {
        double c, s;
        sincos_2pi(xi, c, s);
        const double phi = 2.0 * std::numbers::pi * xi;
        worst = std::max({worst, std::abs(c - std::cos(phi)), std::abs(s - std::sin(phi))});
    }
    EXPECT_LT(worst, 1e-15);  // libm's own argument 2π xi is rounded: ~1 ulp of 2π
}

// Independent chord length of the ray x0 + t d (t >= 0) in the unit cell c.
double chord(const Vec3& x0, const Vec3& d, const std::array<int, 3>& c) {
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (x0[a] < c[a] || x0[a] > c[a] + 1) return 0.0;
            continue;
        }
        double ta = (c[a] - x0[a]) / d[a], tb = (c[a] + 1 - x0[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return std::max(0.0, t1 - t0);
}

TEST(Kernels, WalkMatchesChordLengthsAndExit) {
    const std::array<int, 3> n{13, 9, 11};
    std::mt19937_64 gen(5);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    // A sparse random medium: large empty regions (skipping) around a few dense blobs.
    std::vector<float> kappa(static_cast<size_t>(n[0]) * n[1] * n[2], 0.0f);
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i)
                if ((i > 8 && j < 4) || (k < 3 && i < 4) || U(gen) < 0.05)
                    kappa[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] = static_cast<float>(0.1 + U(gen));
    VoxelGrid vg = make_voxels(n, kappa);
    const GridView g = vg.view({false, false, false});
    for (int ray = 0; ray < 300; ++ray) {
        PathState s;
        std::array<int, 3> c0{};
        for (int a = 0; a < 3; ++a) {
            const double x = U(gen) * n[a];
            c0[a] = std::min(static_cast<int>(x), n[a] - 1);
            s.frac[a] = x - c0[a];
        }
        s.idx = g.index(c0);
        const double mu = 2.0 * U(gen) - 1.0, phi = 2.0 * std::numbers::pi * U(gen), r = std::sqrt(1.0 - mu * mu);
        s.d = {r * std::cos(phi), r * std::sin(phi), mu};
        const Vec3 x0{c0[0] + s.frac[0], c0[1] + s.frac[1], c0[2] + s.frac[2]};
        std::map<std::int64_t, double> seen;
        const int face = walk_optical_depth(g, s, std::numeric_limits<double>::infinity(),
                                            [&](std::int64_t idx, double len) { seen[idx] += len; });
        ASSERT_GE(face, 0);
        // every non-empty cell: the walk's length equals the chord (and only those are reported)
        for (int k = 0; k < n[2]; ++k)
            for (int j = 0; j < n[1]; ++j)
                for (int i = 0; i < n[0]; ++i) {
                    const std::int64_t idx = g.index({i, j, k});
                    EXPECT_EQ(cell_of(g, idx), (std::array<int, 3>{i, j, k}));
                    const bool full = kappa[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] > 0.0f;
                    const double expect = full ? chord(x0, s.d, {i, j, k}) : 0.0;
                    const double got = seen.count(idx) ? seen[idx] : 0.0;
                    EXPECT_NEAR(got, expect, 1e-9) << "ray " << ray << " cell " << i << " " << j << " " << k;
                }
        // the exit point lies on the reported face, on the straight line from x0
        const std::array<int, 3> ce = cell_of(g, s.idx);
        const Vec3 xe{ce[0] + s.frac[0], ce[1] + s.frac[1], ce[2] + s.frac[2]};
        const int axis = face / 2;
        EXPECT_NEAR(xe[axis], face % 2 ? n[axis] : 0.0, 1e-9);
        const double t = (xe[axis] - x0[axis]) / s.d[axis];
        for (int a = 0; a < 3; ++a) EXPECT_NEAR(xe[a], x0[a] + t * s.d[a], 1e-9) << "ray " << ray;
    }
}


TEST(Kernels, WalkOnTheMediumBoxEqualsWalkOnTheDomain) {
    const std::array<int, 3> n{12, 10, 9}, lo{3, 2, 4}, hi{8, 7, 7};
    std::mt19937_64 gen(9);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    const std::array<int, 3> bn{hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    std::vector<float> full(static_cast<size_t>(n[0]) * n[1] * n[2], 0.0f), box(static_cast<size_t>(bn[0]) * bn[1] * bn[2], 0.0f);
    for (int k = lo[2]; k < hi[2]; ++k)
        for (int j = lo[1]; j < hi[1]; ++j)
            for (int i = lo[0]; i < hi[0]; ++i) {
                const float v = U(gen) < 0.6 ? static_cast<float>(0.05 + 0.3 * U(gen)) : 0.0f;
                full[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] = v;
                box[(static_cast<size_t>(k - lo[2]) * bn[1] + (j - lo[1])) * bn[0] + (i - lo[0])] = v;
            }
    VoxelGrid gf = make_voxels(n, full);
    VoxelGrid gb = make_voxels(bn, box);
    gb.origin = lo;
    gb.domain = n;
    const GridView vf = gf.view({false, false, false}), vb = gb.view({false, false, false});
    int faces_seen = 0;
    for (int ray = 0; ray < 2000; ++ray) {
        PathState sf, sb;
        std::array<int, 3> cf{}, cb{};
        for (int a = 0; a < 3; ++a) {
            const double x = lo[a] + U(gen) * bn[a];
            cf[a] = std::min(static_cast<int>(x), hi[a] - 1);
            sf.frac[a] = x - cf[a];
            cb[a] = cf[a] - lo[a];
            sb.frac[a] = sf.frac[a];
        }
        sf.idx = vf.index(cf);
        sb.idx = vb.index(cb);
        const double mu = 2.0 * U(gen) - 1.0, phi = 2.0 * std::numbers::pi * U(gen), r = std::sqrt(1.0 - mu * mu);
        sf.d = sb.d = Vec3{r * std::cos(phi), r * std::sin(phi), mu};
        std::map<std::array<int, 3>, double> segf, segb;
        const double tau = ray % 2 ? std::numeric_limits<double>::infinity() : -std::log(U(gen));
        const int ff = walk_optical_depth(vf, sf, tau, [&](std::int64_t idx, double len) { segf[cell_of(vf, idx)] += len; });
        const int fb = walk_optical_depth(vb, sb, tau, [&](std::int64_t idx, double len) {
            std::array<int, 3> c = cell_of(vb, idx);
            for (int a = 0; a < 3; ++a) c[a] += lo[a];
            segb[c] += len;
        });
        ASSERT_EQ(ff, fb) << "ray " << ray;
        if (ff >= 0) faces_seen |= 1 << ff;
        if (ff < 0)
            for (int a = 0; a < 3; ++a) {
                EXPECT_EQ(cell_of(vf, sf.idx)[a], cell_of(vb, sb.idx)[a] + lo[a]);
                EXPECT_NEAR(sf.frac[a], sb.frac[a], 1e-12);
            }
        ASSERT_EQ(segf.size(), segb.size());
        for (const auto& [c, len] : segf) EXPECT_NEAR(segb[c], len, 1e-12);
    }
    EXPECT_EQ(faces_seen, 63);  // every face of the domain was reached
}


// Unmasked entry samples against the mask: a ray that meets a non-empty cell must start on a
// live pixel; the mask must also drop some area (the media have empty columns). Non-periodic:
// hits by independent chord lengths; periodic in x, y: by the walk (rays wrap).
TEST(Kernels, EntryMaskKeepsEveryRayThatMeetsTheMedium) {
    const std::array<int, 3> n{11, 9, 8};
    std::mt19937_64 gen(21);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<float> kappa(static_cast<size_t>(n[0]) * n[1] * n[2], 0.0f);
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i)
                if ((i > 3 && i < 7 && j > 2 && j < 6 && k > 1 && k < 6) || U(gen) < 0.01)
                    kappa[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] = 0.5f;
    auto nonempty = [&](const std::array<int, 3>& c) {
        return kappa[(static_cast<size_t>(c[2]) * n[1] + c[1]) * n[0] + c[0]] > 0.0f;
    };
    VoxelGrid vg = make_voxels(n, kappa);
    for (const bool periodic_xy : {false, true}) {
        const std::array<bool, 3> periodic{periodic_xy, periodic_xy, false};
        const GridView g = vg.view(periodic);
        const auto surface = surface_cells(n, periodic, nonempty);
        int narrowed = 0;
        for (int dir = 0; dir < 12; ++dir) {
            const double mu = -0.1 - 0.9 * U(gen), phi = 2.0 * std::numbers::pi * U(gen), r = std::sqrt(1.0 - mu * mu);
            const Vec3 w{r * std::cos(phi), r * std::sin(phi), mu};
            const EntrySampler all({0, 0, 0}, n, periodic, w);
            EntrySampler live = all;
            live.restrict_to(surface, periodic, w);
            EXPECT_LE(live.projected_area, all.projected_area);
            narrowed += live.projected_area < all.projected_area;
            int hits = 0;
            for (std::uint64_t p = 0; p < 3000; ++p) {
                PathRng rng(3, static_cast<std::uint32_t>(dir), p);
                PathState s;
                s.d = w;
                all.sample(rng, g, s);
                const std::array<int, 3> c0 = cell_of(g, s.idx);
                const Vec3 x0{c0[0] + s.frac[0], c0[1] + s.frac[1], c0[2] + s.frac[2]};
                bool hit = false;
                if (periodic_xy) {
                    PathState t = s;
                    walk_optical_depth(g, t, std::numeric_limits<double>::infinity(), [&](std::int64_t, double len) { hit |= len > 0; });
                } else {
                    for (int k = 0; k < n[2] && !hit; ++k)
                        for (int j = 0; j < n[1] && !hit; ++j)
                            for (int i = 0; i < n[0] && !hit; ++i)
                                hit = nonempty({i, j, k}) && chord(x0, w, {i, j, k}) > 0.0;
                }
                if (!hit) continue;
                ++hits;
                // the face it starts on (the plane it lies on; corners are measure zero)
                bool live_pixel = false;
                for (int f = 0; f < live.nfaces; ++f) {
                    const int a = live.face[f] / 2;
                    if (x0[a] != (live.face[f] % 2 ? n[a] : 0.0)) continue;
                    const int u = (a + 1) % 3, v = (a + 2) % 3;
                    const std::int32_t pixel = c0[u] + n[u] * c0[v];
                    live_pixel |= !live.masked[f] ||
                                  std::find(live.live[f].begin(), live.live[f].end(), pixel) != live.live[f].end();
                }
                EXPECT_TRUE(live_pixel) << "ray " << p << " of direction " << dir << (periodic_xy ? " (periodic)" : "");
            }
            EXPECT_GT(hits, 100);
        }
        EXPECT_GT(narrowed, 6);
    }
}

}  // namespace
}  // namespace nimbus::mc
