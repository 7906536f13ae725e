// Henyey-Greenstein invariants: normalized to 1 over the sphere, mean cosine g, and the sampler
// draws from the same density.
#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "src/physics/phase.h"

namespace nimbus {
namespace {

// ∫ f(mu) 2π dmu by composite Simpson on a fine grid (HG is smooth for |g| <= 0.9).
template <class F>
double sphere_integral(F f) {
    const int n = 200000;
    double s = 0;
    for (int q = 0; q <= n; ++q) {
        const double mu = -1.0 + 2.0 * q / n;
        const double w = (q == 0 || q == n) ? 1 : (q % 2 ? 4 : 2);
        s += w * f(mu);
    }
    return 2.0 * std::numbers::pi * s * (2.0 / n) / 3.0;
}

TEST(HenyeyGreenstein, NormalizedToOneWithMeanCosineG) {
    for (double g : {-0.5, 0.0, 0.3, 0.85, 0.9}) {
        EXPECT_NEAR(sphere_integral([&](double mu) { return hg_phase(g, mu); }), 1.0, 1e-9) << g;
        EXPECT_NEAR(sphere_integral([&](double mu) { return mu * hg_phase(g, mu); }), g, 1e-9) << g;
    }
    EXPECT_NEAR(hg_phase(0.0, 0.3), 1.0 / (4 * std::numbers::pi), 1e-15);
}

TEST(HenyeyGreenstein, SamplerMatchesDensity) {
    // Mean of mu and of mu² from the sampler against ∫ mu^n p dw (<mu²> = (1 + 2 g²)/3 for HG).
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    for (double g : {0.0, 0.5, 0.85, -0.3}) {
        const int n = 400000;
        double m1 = 0, m2 = 0;
        for (int s = 0; s < n; ++s) {
            const double mu = hg_sample_mu(g, u(rng));
            m1 += mu;
            m2 += mu * mu;
        }
        m1 /= n;
        m2 /= n;
        const double sd1 = std::sqrt((1 + 2 * g * g) / 3 - g * g) / std::sqrt(n);
        EXPECT_LT(std::abs(m1 - g), 4 * sd1) << g;
        // E[P_l(mu)] = g^l: E[mu²] = (1 + 2g²)/3 and E[mu⁴] = (8g⁴ + 20g² + 7)/35 (mu⁴ = (8P4 + 20P2 + 7)/35)
        const double e2 = (1 + 2 * g * g) / 3, e4 = (8 * g * g * g * g + 20 * g * g + 7) / 35;
        const double sd2 = std::sqrt(e4 - e2 * e2) / std::sqrt(n);
        EXPECT_LT(std::abs(m2 - e2), 4 * sd2) << g;
    }
}

TEST(Directions, RotateKeepsAngleToAxis) {
    const Vec3 w = normalized(Vec3{0.3, -0.5, 0.8});
    for (double mu : {-0.9, 0.0, 0.4, 1.0}) {
        const Vec3 v = rotate_direction(w, mu, 1.234);
        EXPECT_NEAR(norm(v), 1.0, 1e-12);
        EXPECT_NEAR(dot(v, w), mu, 1e-12);
    }
}

}  // namespace
}  // namespace nimbus
