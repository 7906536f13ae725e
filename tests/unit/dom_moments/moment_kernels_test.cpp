// The DOM moment operators (solvers/dom/moment_kernels.h) on random operators and data against a
// plain triple loop: source S = A·P + s·Y and moments phi += psi·wY^T, fluence += psi·w,
// flux += psi·(w Ω), for every octant size and moment count the dispatch knows plus odd ones
// (the portable fallback), an odd cell count (remainder blocks), a psi stride larger than nd,
// and a guard value after the source buffer's 3 allowed overrun values. Both code paths; the
// AVX2 one only where the CPU has it. Plus one physical invariant: isotropic psi = c gives
// fluence c Σ w, flux 0 on a symmetric set, and phi_0 = c Σ w Y_0.
#include "solvers/dom/moment_kernels.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace nimbus::dom {
namespace {

struct Sizes {
    int nd, nmom, nl;
};

std::vector<Sizes> all_sizes() {
    std::vector<Sizes> v;
    for (int nd : {1, 3, 5, 6, 10, 12, 16, 21, 36, 37})
        for (int nmom : {0, 1, 4, 7, 9, 16, 25, 36, 49, 64})  // 0: fluence and flux alone
            for (int nl : {0, 2}) v.push_back({nd, nmom, nl});
    return v;
}

std::vector<double> random_values(std::mt19937& rng, size_t n) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> v(n);
    for (double& x : v) x = u(rng);
    return v;
}

// Relative to the size of the terms summed: |a - b| <= 1e-13 (1 + Σ|terms|).
void expect_close(double got, double want, double scale, const char* what, int c, int i) {
    EXPECT_LE(std::abs(got - want), 1e-13 * (1.0 + scale)) << what << " cell " << c << " index " << i;
}

std::vector<MomentPath> paths() {
    std::vector<MomentPath> p{MomentPath::portable};
    if (avx2_available()) p.push_back(MomentPath::avx2);
    return p;
}

TEST(DomMoments, SourceEqualsTripleLoop) {
    std::mt19937 rng(7);
    const int ncell = 13;
    const double guard = 12345.0;
    for (const Sizes& z : all_sizes()) {
        const auto P = random_values(rng, static_cast<size_t>(z.nl * z.nd));
        const auto Y = random_values(rng, static_cast<size_t>(z.nmom * z.nd));
        const auto A = random_values(rng, static_cast<size_t>(ncell * z.nl));
        const auto s = random_values(rng, static_cast<size_t>(ncell * z.nmom));
        const OctantSourceOp op = make_octant_source_op(z.nd, z.nl, z.nmom, P.data(), Y.data());
        for (MomentPath path : paths()) {
            std::vector<double> S(static_cast<size_t>(ncell * z.nd + 3 + 1), -7.0);
            S.back() = guard;
            apply_source(op, ncell, z.nl > 0 ? A.data() : nullptr, s.data(), S.data(), path);
            EXPECT_EQ(S.back(), guard) << "nd " << z.nd << " wrote past the allowed 3 values";
            for (int c = 0; c < ncell; ++c)
                for (int n = 0; n < z.nd; ++n) {
                    double want = 0.0, scale = 0.0;
                    for (int l = 0; l < z.nl; ++l) {
                        want += A[c * z.nl + l] * P[l * z.nd + n];
                        scale += std::abs(A[c * z.nl + l] * P[l * z.nd + n]);
                    }
                    for (int k = 0; k < z.nmom; ++k) {
                        want += s[c * z.nmom + k] * Y[k * z.nd + n];
                        scale += std::abs(s[c * z.nmom + k] * Y[k * z.nd + n]);
                    }
                    expect_close(S[static_cast<size_t>(c * z.nd + n)], want, scale, "S", c, n);
                }
        }
    }
}

TEST(DomMoments, MomentsFluenceFluxEqualTripleLoop) {
    std::mt19937 rng(11);
    const int ncell = 13;
    for (const Sizes& z : all_sizes()) {
        if (z.nl != 0) continue;
        const int stride = z.nd + 5;  // face values or ghost data between cells
        const auto wY = random_values(rng, static_cast<size_t>(z.nmom * z.nd));
        const auto psi = random_values(rng, static_cast<size_t>(ncell * stride));
        const auto phi0 = random_values(rng, static_cast<size_t>(ncell * z.nmom));
        const auto f0 = random_values(rng, static_cast<size_t>(ncell));
        const auto F0 = random_values(rng, static_cast<size_t>(3 * ncell));
        std::vector<double> w(static_cast<size_t>(z.nd));
        std::vector<Vec3> dir(static_cast<size_t>(z.nd));
        std::uniform_real_distribution<double> u(0.1, 1.0);
        for (int n = 0; n < z.nd; ++n) {
            w[static_cast<size_t>(n)] = u(rng);
            const Vec3 v{u(rng), -u(rng), u(rng)};
            dir[static_cast<size_t>(n)] = v / std::sqrt(dot(v, v));
        }
        const OctantMomentOp op = make_octant_moment_op(z.nd, z.nmom, wY.data(), w.data(), dir.data());
        for (MomentPath path : paths()) {
            auto phi = phi0;
            auto f = f0;
            auto F = F0;
            apply_moments(op, ncell, psi.data(), stride, phi.data(), f.data(), F.data(), path);
            for (int c = 0; c < ncell; ++c) {
                const double* p = psi.data() + c * stride;
                for (int k = 0; k < z.nmom; ++k) {
                    double want = phi0[static_cast<size_t>(c * z.nmom + k)], scale = std::abs(want);
                    for (int n = 0; n < z.nd; ++n) {
                        want += wY[static_cast<size_t>(k * z.nd + n)] * p[n];
                        scale += std::abs(wY[static_cast<size_t>(k * z.nd + n)] * p[n]);
                    }
                    expect_close(phi[static_cast<size_t>(c * z.nmom + k)], want, scale, "phi", c, k);
                }
                double wf = f0[static_cast<size_t>(c)], sf = std::abs(wf);
                double wF[3], sF[3];
                for (int a = 0; a < 3; ++a) sF[a] = std::abs(wF[a] = F0[static_cast<size_t>(3 * c + a)]);
                for (int n = 0; n < z.nd; ++n) {
                    const double wp = w[static_cast<size_t>(n)] * p[n];
                    wf += wp;
                    sf += std::abs(wp);
                    for (int a = 0; a < 3; ++a) {
                        wF[a] += wp * dir[static_cast<size_t>(n)][a];
                        sF[a] += std::abs(wp * dir[static_cast<size_t>(n)][a]);
                    }
                }
                expect_close(f[static_cast<size_t>(c)], wf, sf, "fluence", c, 0);
                for (int a = 0; a < 3; ++a) expect_close(F[static_cast<size_t>(3 * c + a)], wF[a], sF[a], "flux", c, a);
            }
        }
    }
}

// The 8 octants of a symmetric set (directions (±a, ±b, ±c), weight 4π/8 each) with psi = 2:
// fluence 2·4π, flux 0, phi_0 = 2·4π·Y_0, Y_0 = 1/sqrt(4π).
TEST(DomMoments, IsotropicRadianceGivesFluenceAndNoFlux) {
    const double Y0 = 1.0 / std::sqrt(4.0 * std::numbers::pi);
    const Vec3 d0 = Vec3{1.0, 2.0, 3.0} / std::sqrt(14.0);
    const int ncell = 5;
    for (MomentPath path : paths()) {
        std::vector<double> phi(static_cast<size_t>(ncell * 9), 0.0), f(ncell, 0.0), F(3 * ncell, 0.0);
        for (int o = 0; o < 8; ++o) {
            const Vec3 d{o & 1 ? d0.x : -d0.x, o & 2 ? d0.y : -d0.y, o & 4 ? d0.z : -d0.z};
            const double w = 4.0 * std::numbers::pi / 8.0;
            std::vector<double> wY(9, 0.0);
            wY[0] = w * Y0;
            const OctantMomentOp op = make_octant_moment_op(1, 9, wY.data(), &w, &d);
            const std::vector<double> psi(ncell, 2.0);
            apply_moments(op, ncell, psi.data(), 1, phi.data(), f.data(), F.data(), path);
        }
        for (int c = 0; c < ncell; ++c) {
            EXPECT_NEAR(f[static_cast<size_t>(c)], 8.0 * std::numbers::pi, 1e-13);
            EXPECT_NEAR(phi[static_cast<size_t>(9 * c)], 8.0 * std::numbers::pi * Y0, 1e-13);
            for (int a = 0; a < 3; ++a) EXPECT_NEAR(F[static_cast<size_t>(3 * c + a)], 0.0, 1e-13);
        }
    }
}

}  // namespace
}  // namespace nimbus::dom
