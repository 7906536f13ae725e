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
        EXPECT_NEAR(m2, (1 + 2 * g * g) / 3, 5e-3) << g;
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
