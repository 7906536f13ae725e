// The per-ray and per-row kernels of the light propagation maps (solvers/lpm/segment_kernel.h,
// gather_kernel.h), against independent answers:
//   - advance_rays against the exact segment of dL/ds = -kappa L + u (in long double),
//     L1 = L0 e^{-tau} + u s f1, ∫L ds = s (L0 f1 + u s f2), f1 = (1-e^{-tau})/tau, f2 = (1-f1)/tau,
//     from tau = 0 to 700, on a run length that is not a multiple of the vector width. The
//     kernel's f2 loses digits just above its series threshold (tau = 1e-3: ~2e-10 relative,
//     a known limit, harmless for the physics and not for energy: the bookkeeping uses the
//     same f1, f2); the test allows exactly that bound;
//   - advance_rays_vacuum is bit for bit advance_rays at kappa = 0, u = 0 (the map sweep
//     relies on this to skip the exponential in empty cells without changing any result);
//   - gather_directions against the plain double loop Σ_l C[l][c] phi_l[i] for every
//     specialized column count and a generic one, with the phi rows zeroed afterwards.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "solvers/lpm/gather_kernel.h"
#include "solvers/lpm/segment_kernel.h"

namespace nimbus {
namespace {

TEST(LpmKernel, AdvanceRaysMatchesTheClosedFormSegment) {
    const double taus[] = {0.0, 1e-12, 1e-6, 5e-4, 9.99e-4, 1e-3, 1.001e-3, 0.01, 0.3, 1.0, 2.5, 10.0, 40.0, 300.0, 700.0};
    const int n = static_cast<int>(std::size(taus));
    const double len = 2.0, w = 0.7;
    std::vector<double> L(n), K(n), Us(n), phi(n, 0.25);
    for (int i = 0; i < n; ++i) {
        L[static_cast<size_t>(i)] = 1.0 + 0.1 * i;
        K[static_cast<size_t>(i)] = taus[i] / len;
        Us[static_cast<size_t>(i)] = 0.3 + 0.05 * i;
    }
    const std::vector<double> L0 = L;
    lpm::advance_rays(n, L.data(), K.data(), Us.data(), phi.data(), len, w);
    for (int i = 0; i < n; ++i) {
        const size_t s = static_cast<size_t>(i);
        const double tau = K[s] * len, u = Us[s], l0 = L0[s];
        // Reference in long double: f1 = (1 - e^{-tau})/tau and f2 = (1 - f1)/tau from their
        // Taylor series below tau = 0.1 (30 terms), from the closed form above.
        long double f1 = 0, f2 = 0;
        if (tau < 0.1) {
            long double term1 = 1, term2 = 0.5L;  // (-tau)^k/(k+1)!, (-tau)^k/(k+2)!
            for (int k = 0; k < 30; ++k) {
                f1 += term1;
                f2 += term2;
                term1 *= -static_cast<long double>(tau) / (k + 2);
                term2 *= -static_cast<long double>(tau) / (k + 3);
            }
        } else {
            f1 = -std::expm1(-static_cast<long double>(tau)) / tau;
            f2 = (1 - f1) / tau;
        }
        const long double e = 1 - tau * f1;
        const double L1 = static_cast<double>(l0 * e + u * len * f1);
        const double mean = static_cast<double>(l0 * f1 + u * len * f2);  // ∫L ds / len
        // Kernel error bound: rounding (1e-14 relative), plus the cancellation in its
        // f1 = (1 - e)/tau and f2 = (1 - f1)/tau above its series threshold tau = 1e-3:
        // |δf1| <= 2 eps / tau, |δf2| <= 4 eps / tau².
        const double eps = 2.3e-16;
        const double df1 = tau >= 1e-3 ? 2 * eps / tau : 0.0, df2 = tau >= 1e-3 ? 4 * eps / (tau * tau) : 0.0;
        EXPECT_NEAR(L[s], L1, 1e-14 * std::abs(L1) + u * len * df1) << "tau " << tau;
        EXPECT_NEAR(phi[s], 0.25 + w * mean, 1e-14 * (0.25 + w * mean) + w * (l0 * df1 + u * len * df2)) << "tau " << tau;
    }
}

TEST(LpmKernel, VacuumKernelIsBitForBitTheFullKernelAtZeroExtinction) {
    for (int n : {1, 3, 4, 7, 64, 65}) {
        std::vector<double> L(static_cast<size_t>(n)), zero(static_cast<size_t>(n), 0.0), phi_a(L.size()), phi_b;
        for (int i = 0; i < n; ++i) {
            L[static_cast<size_t>(i)] = std::exp(0.37 * i) * 1e-3 + 1.0 / (i + 3);
            phi_a[static_cast<size_t>(i)] = std::sqrt(i + 0.5);
        }
        phi_b = phi_a;
        std::vector<double> La = L;
        lpm::advance_rays(n, La.data(), zero.data(), zero.data(), phi_a.data(), 1.7, 0.0123);
        lpm::advance_rays_vacuum(n, L.data(), phi_b.data(), 0.0123);
        for (size_t i = 0; i < L.size(); ++i) {
            EXPECT_EQ(La[i], L[i]);
            EXPECT_EQ(phi_a[i], phi_b[i]);
        }
    }
}

TEST(LpmKernel, GatherIsTheDirectionSumAndClearsTheRows) {
    const int nl = 9;
    const size_t stride = 80;
    for (int nc : {1, 4, 7, 10, 13}) {
        for (int n : {3, 4, 61, 64}) {
            const int cs = nc + 2;  // the caller may use only the leading columns of C
            std::vector<double> phi(stride * nl), C(static_cast<size_t>(nl * cs)), out(static_cast<size_t>(nc) * 70, -1.0);
            for (size_t i = 0; i < phi.size(); ++i) phi[i] = std::sin(0.1 * static_cast<double>(i)) + 1.5;
            for (size_t i = 0; i < C.size(); ++i) C[i] = std::cos(0.7 * static_cast<double>(i));
            const std::vector<double> phi0 = phi;
            lpm::gather_directions(n, nl, phi.data(), stride, C.data(), cs, nc, out.data(), 70);
            for (int c = 0; c < nc; ++c)
                for (int i = 0; i < n; ++i) {
                    double ref = 0.0, mag = 0.0;
                    for (int l = 0; l < nl; ++l) {
                        const double t = C[static_cast<size_t>(l * cs + c)] * phi0[static_cast<size_t>(l) * stride + i];
                        ref += t;
                        mag += std::abs(t);
                    }
                    EXPECT_NEAR(out[static_cast<size_t>(c) * 70 + i], ref, 1e-15 * nl * mag) << nc << " " << n;
                }
            for (int l = 0; l < nl; ++l)
                for (size_t i = 0; i < stride; ++i) {
                    const double v = phi[static_cast<size_t>(l) * stride + i];
                    EXPECT_EQ(v, i < static_cast<size_t>(n) ? 0.0 : phi0[static_cast<size_t>(l) * stride + i]);
                }
        }
    }
}

}  // namespace
}  // namespace nimbus
