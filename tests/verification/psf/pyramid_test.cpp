// The light-volume pyramid (solvers/psf/pyramid.h): energy preserved per level, the stored blur
// width of each level equals the measured spread of a smooth blob, and the distributed and
// replicated levels agree with a single-rank build.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "solvers/psf/pyramid.h"
#include "src/core/decomposition.h"

namespace nimbus::psf {
namespace {

template <class Fn>
Field<double> make_level0(const Decomposition& d, Fn&& f, int nc) {
    Field<double> out(d.local(), 3, nc, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        for (int c = 0; c < nc; ++c) out(i, j, k, c) = f(i, j, k, c);
    });
    return out;
}

// Σ over the global level of value x (cell volume) for component c, and the first and second
// moments along each axis (cell centres, metres).
struct Moments {
    double mass = 0, mean[3] = {0, 0, 0}, var[3] = {0, 0, 0};
};

Moments level_moments(const PyramidLevel& lv, const Decomposition& d, int c) {
    Box own = lv.replicated ? Box{{0, 0, 0}, lv.n} : lv.values.owned();
    const bool count_here = !lv.replicated || d.rank() == 0;
    double s[7] = {0, 0, 0, 0, 0, 0, 0};
    if (count_here)
        for_each_cell(own, [&](int i, int j, int k) {
            const double v = lv.values(i, j, k, c) * lv.h * lv.h * lv.h;
            const double x[3] = {lv.offset[0] + (i + 0.5) * lv.h, lv.offset[1] + (j + 0.5) * lv.h,
                                 lv.offset[2] + (k + 0.5) * lv.h};
            s[0] += v;
            for (int a = 0; a < 3; ++a) s[1 + a] += v * x[a], s[4 + a] += v * x[a] * x[a];
        });
    double t[7];
    MPI_Allreduce(s, t, 7, MPI_DOUBLE, MPI_SUM, d.comm());
    Moments m;
    m.mass = t[0];
    for (int a = 0; a < 3; ++a) {
        m.mean[a] = t[1 + a] / t[0];
        m.var[a] = t[4 + a] / t[0] - m.mean[a] * m.mean[a];
    }
    return m;
}

TEST(PsfPyramid, EnergyPreservedOnEveryLevel) {
    const Decomposition d(MPI_COMM_WORLD, {32, 32, 64});
    Grid g;
    g.n = {32, 32, 64};
    g.h = 0.5;
    // Two components: a lumpy positive field reaching the boundaries, and a constant.
    auto f = [](int i, int j, int k, int c) {
        return c == 0 ? 1.0 + std::sin(0.7 * i) * std::cos(0.3 * j + 0.2 * k) + 0.01 * ((i * 7 + j * 13 + k * 5) % 11)
                      : 2.5;
    };
    const LightPyramid p(make_level0(d, f, 2), g, d, 0);
    ASSERT_GE(p.size(), 5);
    const Moments m0 = level_moments(p.level(0), d, 0), c0 = level_moments(p.level(0), d, 1);
    bool any_distributed = false, any_replicated = false;
    for (int k = 0; k < p.size(); ++k) {
        const PyramidLevel& lv = p.level(k);
        any_distributed = any_distributed || (k > 0 && !lv.replicated);
        any_replicated = any_replicated || lv.replicated;
        const Moments m = level_moments(lv, d, 0), c = level_moments(lv, d, 1);
        if (d.rank() == 0)
            std::printf("  level %d: n %3d %3d %3d  h %5.2f m  w %6.3f m  sigma %.3f  r %d  %s  energy ratio %.8f\n",
                        k, lv.n[0], lv.n[1], lv.n[2], lv.h, lv.width, lv.sigma[0], lv.radius[0],
                        lv.replicated ? "replicated " : "distributed", m.mass / m0.mass);
        EXPECT_NEAR(m.mass / m0.mass, 1.0, 1e-6) << "level " << k;  // float storage
        EXPECT_NEAR(c.mass / c0.mass, 1.0, 1e-6) << "level " << k;
        EXPECT_DOUBLE_EQ(lv.width, k == 0 ? 0.0 : g.h * (1 << k));
    }
    if (d.size() > 1) {
        EXPECT_TRUE(any_distributed);
    }
    EXPECT_TRUE(any_replicated);
}

TEST(PsfPyramid, StoredWidthIsTheMeasuredSpreadOfABlob) {
    // A Gaussian blob of standard deviation s0 at the centre of the grid: level k should hold a
    // blob of variance s0² + w_k² per axis (truncated kernels and sampling: < 1%), centred where
    // it was. 64 halves evenly; 63 x 62 x 61 gives odd counts on some level of every axis, whose
    // (1/4, 1/2, 1/4) resampling adds h_k²/8 instead of h_k²/16 (pyramid.h).
    for (const Int3 n : {Int3{64, 64, 64}, Int3{63, 62, 61}}) {
        const Decomposition d(MPI_COMM_WORLD, n);
        Grid g;
        g.n = n;
        g.h = 1.0;
        const double s0 = 3.0;
        const double c[3] = {0.5 * n[0], 0.5 * n[1], 0.5 * n[2]};
        auto f = [&](int i, int j, int k, int) {
            const double x = i + 0.5 - c[0], y = j + 0.5 - c[1], z = k + 0.5 - c[2];
            return std::exp(-(x * x + y * y + z * z) / (2.0 * s0 * s0));
        };
        const LightPyramid p(make_level0(d, f, 1), g, d, 5);
        for (int k = 0; k < 4; ++k) {
            const PyramidLevel& lv = p.level(k);
            const Moments m = level_moments(lv, d, 0);
            for (int a = 0; a < 3; ++a) {
                const double expect = s0 * s0 + lv.width * lv.width;
                EXPECT_NEAR(m.var[a] / expect, 1.0, 0.01) << "n " << n[a] << " level " << k << " axis " << a;
                EXPECT_NEAR(m.mean[a], c[a], 1e-6 * c[a]) << "n " << n[a] << " level " << k << " axis " << a;
            }
            if (d.rank() == 0)
                std::printf("  %d³-ish level %d: measured sqrt(var - s0²) = %.4f %.4f %.4f m, stored w = %.4f m\n",
                            n[0], k, std::sqrt(std::max(0.0, m.var[0] - s0 * s0)),
                            std::sqrt(std::max(0.0, m.var[1] - s0 * s0)), std::sqrt(std::max(0.0, m.var[2] - s0 * s0)),
                            lv.width);
        }
    }
}

// Every level is centred on the domain, so a field symmetric under the x, y and z mirrors gives
// mirror-symmetric levels and lookups on odd grids too. Halving from the origin put the coarse
// cells of an odd level half a fine cell off centre (a centred sphere came out 3-12% asymmetric).
TEST(PsfPyramid, LevelsAreMirrorSymmetricOnOddGrids) {
    Grid g;
    g.n = {21, 22, 41};
    g.h = 1.5;
    const Decomposition d(MPI_COMM_WORLD, g.n);
    auto f = [&](int i, int j, int k, int) {
        const double x = i + 0.5 - 10.5, y = j + 0.5 - 11.0, z = k + 0.5 - 20.5;
        return std::exp(-0.02 * (x * x + 2.0 * y * y) - 0.01 * z * z) + (std::abs(x) < 3.0 ? 0.5 : 0.0);
    };
    const LightPyramid p(make_level0(d, f, 1), g, d, 0);
    ASSERT_GE(p.size(), 4);
    for (int k = 0; k < p.size(); ++k) {
        const PyramidLevel& lv = p.level(k);
        const Field<float> all = gather_layers(lv, 0, lv.n[2], MPI_COMM_WORLD);
        double worst = 0.0, peak = 0.0;
        for_each_cell(Box{{0, 0, 0}, lv.n}, [&](int i, int j, int k2) {
            const double v = all(i, j, k2);
            peak = std::max(peak, v);
            worst = std::max({worst, std::abs(v - all(lv.n[0] - 1 - i, j, k2)),
                              std::abs(v - all(i, lv.n[1] - 1 - j, k2)), std::abs(v - all(i, j, lv.n[2] - 1 - k2))});
        });
        EXPECT_LE(worst, 1e-6 * peak) << "level " << k << " n " << lv.n[0] << " " << lv.n[1] << " " << lv.n[2];
        // Lookups at mirrored world points agree (trilinear between the centred cells).
        const Vec3 lo = p.origin(), L{g.n[0] * g.h, g.n[1] * g.h, g.n[2] * g.h};
        double worst_lookup = 0.0;
        for (double t : {0.03, 0.21, 0.37, 0.5}) {
            const Vec3 x{lo[0] + t * L[0], lo[1] + (0.5 - 0.3 * t) * L[1], lo[2] + (0.2 + t) * L[2]};
            const Vec3 xm{lo[0] + (1.0 - t) * L[0], x[1], x[2]};
            float a = 0.0f, b = 0.0f;
            sample_level(all, lv, p.origin(), x, &a);
            sample_level(all, lv, p.origin(), xm, &b);
            worst_lookup = std::max(worst_lookup, static_cast<double>(std::abs(a - b)));
        }
        EXPECT_LE(worst_lookup, 1e-6 * peak) << "level " << k;
    }
}

// On periodic x and y the pyramid blurs across the seam: it commutes with periodic shifts. A
// blob next to the x = 0 face, and the same blob moved 8 cells on along x: level k of the second
// is level k of the first moved 8/2^k cells (k <= 3). Mirroring at the faces (what the pyramid
// did on every axis) gives the blob at the face a mirror image instead of its periodic copy.
TEST(PsfPyramid, PeriodicAxesCommuteWithShifts) {
    Grid g;
    g.n = {32, 16, 32};
    g.h = 1.0;
    const Decomposition d(MPI_COMM_WORLD, g.n, {1, 1, 0}, {true, true, false});
    const int shift = 8;
    auto blob = [&](int offset) {
        return [=](int i, int j, int k, int) {
            const double x = ((i - offset) % 32 + 32) % 32 + 0.5 - 1.0, y = j + 0.5 - 8.0, z = k + 0.5 - 16.0;
            const double xp = std::min(std::abs(x), 32.0 - std::abs(x));  // periodic distance
            return std::exp(-(xp * xp + y * y + z * z) / 8.0);
        };
    };
    const LightPyramid a(make_level0(d, blob(0), 1), g, d, 4), b(make_level0(d, blob(shift), 1), g, d, 4);
    for (int k = 0; k < 4; ++k) {
        const PyramidLevel& la = a.level(k);
        const Field<float> fa = gather_layers(la, 0, la.n[2], MPI_COMM_WORLD);
        const Field<float> fb = gather_layers(b.level(k), 0, la.n[2], MPI_COMM_WORLD);
        const int s = shift >> k;
        double worst = 0.0, peak = 0.0;
        for_each_cell(Box{{0, 0, 0}, la.n}, [&](int i, int j, int k2) {
            const double va = fa(i, j, k2), vb = fb((i + s) % la.n[0], j, k2);
            worst = std::max(worst, std::abs(va - vb));
            peak = std::max(peak, va);
        });
        EXPECT_LE(worst, 1e-6 * peak) << "level " << k;
    }
}

TEST(PsfPyramid, DistributedLevelsEqualSingleRankBuild) {
    Grid g;
    g.n = {24, 20, 64};
    g.h = 2.0;
    auto f = [](int i, int j, int k, int) { return std::exp(-0.05 * k) * (1.0 + 0.3 * std::sin(0.9 * i + 0.4 * j)); };
    const Decomposition dw(MPI_COMM_WORLD, g.n), ds(MPI_COMM_SELF, g.n);
    const LightPyramid pw(make_level0(dw, f, 1), g, dw, 0), ps(make_level0(ds, f, 1), g, ds, 0);
    ASSERT_EQ(pw.size(), ps.size());
    for (int k = 0; k < pw.size(); ++k) {
        const PyramidLevel& lw = pw.level(k);
        const Field<float> all = gather_layers(lw, 0, lw.n[2], MPI_COMM_WORLD);
        double worst = 0.0;
        for_each_cell(Box{{0, 0, 0}, lw.n}, [&](int i, int j, int k2) {
            worst = std::max(worst, std::abs(static_cast<double>(all(i, j, k2)) - ps.level(k).values(i, j, k2)));
        });
        EXPECT_LE(worst, 1e-6) << "level " << k;
    }
}

}  // namespace
}  // namespace nimbus::psf
