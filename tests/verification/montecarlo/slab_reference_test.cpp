// Checks of the independent slab reference (tests/support/slab_reference): energy
// conservation, quadrature, the conservative isotropic half-space (Chandrasekhar's H-function
// solved here independently by its integral equation), and the interior profile's absorption.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/support/slab_reference.h"

namespace nimbus::test {
namespace {

TEST(SlabReference, GaussLegendreIntegratesPolynomials) {
    std::vector<double> x, w;
    gauss_legendre(16, 0.0, 1.0, x, w);
    for (int p = 0; p <= 31; ++p) {
        double s = 0.0;
        for (size_t i = 0; i < x.size(); ++i) s += w[i] * std::pow(x[i], p);
        EXPECT_NEAR(s, 1.0 / (p + 1), 1e-14) << "degree " << p;
    }
}

// Conservative scattering: R + T_diffuse + T_direct = 1. The single-scatter initial layer
// (1e-10 thick) and ~35 doublings leave about 1e-6: 1000x below the Monte Carlo errors.
TEST(SlabReference, ConservesEnergyWithoutAbsorption) {
    for (double g : {0.0, 0.85})
        for (double tau0 : {1.0, 10.0})
            for (double mu0 : {1.0, 0.5}) {
                const SlabSolution s = solve_slab({tau0, 1.0, g, mu0});
                EXPECT_NEAR(s.reflected + s.transmitted_diffuse + s.transmitted_direct, 1.0, 2e-6)
                    << "g " << g << " tau0 " << tau0 << " mu0 " << mu0;
            }
}

// Pure absorber: no diffuse light at all.
TEST(SlabReference, PureAbsorberHasNoDiffuseLight) {
    const SlabSolution s = solve_slab({2.0, 0.0, 0.5, 0.7});
    EXPECT_EQ(s.reflected, 0.0);
    EXPECT_EQ(s.transmitted_diffuse, 0.0);
    EXPECT_DOUBLE_EQ(s.transmitted_direct, std::exp(-2.0 / 0.7));
}

// Absorbing slab: absorption from the interior profile, A = (1 - a) ∫ (phi_d + e^{-tau/mu0}) dtau
// / mu0 (Simpson), closes R + T + A = 1: checks the profile against the boundary fluxes.
TEST(SlabReference, ProfileAbsorptionClosesTheBalance) {
    for (double g : {0.0, 0.85}) {
        SlabProblem p{1.0, 0.9, g, 0.5};
        p.profile_levels = 256;
        const SlabSolution s = solve_slab(p);
        double integral = 0.0;
        const double h = p.tau0 / p.profile_levels;
        for (int k = 0; k <= p.profile_levels; ++k) {
            const double f = s.fluence[static_cast<size_t>(k)] + std::exp(-s.tau[static_cast<size_t>(k)] / p.mu0);
            const double wgt = (k == 0 || k == p.profile_levels) ? 1.0 : (k % 2 ? 4.0 : 2.0);
            integral += wgt * f * h / 3.0;
        }
        const double A = (1.0 - p.albedo) * integral / p.mu0;
        EXPECT_NEAR(s.reflected + s.transmitted_diffuse + s.transmitted_direct + A, 1.0, 2e-6) << "g " << g;
    }
}

// Conservative isotropic half-space (Chandrasekhar 1960, ch. IV): the reflected radiance is
//   I(0, mu) = E0 / (4π) mu0 / (mu + mu0) H(mu) H(mu0),
// with H from  1/H(mu) = (1/2) ∫_0^1 mu' H(mu') / (mu + mu') dmu'  (a = 1), solved here by
// iteration on a fine Gauss grid (geometric-mean damping: the plain iteration maps c H to
// H / c and never settles the scale); H(1) = 2.9078 (Chandrasekhar's table).
TEST(SlabReference, MatchesChandrasekharHalfSpace) {
    std::vector<double> x, w;
    gauss_legendre(400, 0.0, 1.0, x, w);
    std::vector<double> H(x.size(), 1.0);
    auto H_at = [&](double mu) {
        double s = 0.0;
        for (size_t j = 0; j < x.size(); ++j) s += 0.5 * w[j] * x[j] * H[j] / (mu + x[j]);
        return 1.0 / s;
    };
    for (int it = 0; it < 200; ++it) {
        std::vector<double> next(x.size());
        for (size_t i = 0; i < x.size(); ++i) next[i] = std::sqrt(H[i] * H_at(x[i]));
        H = next;
    }
    EXPECT_NEAR(H_at(1.0), 2.9078, 2e-4);
    const double mu0 = 0.6;
    const SlabSolution s = solve_slab({16384.0, 1.0, 0.0, mu0});
    EXPECT_NEAR(s.reflected, 1.0, 1e-3);  // 1/(0.75 tau0) transmitted + doubling error
    for (size_t i = 0; i < s.mu.size(); i += 5) {
        const double expect = mu0 / (s.mu[i] + mu0) * H_at(s.mu[i]) * H_at(mu0) / (4.0 * std::numbers::pi);
        EXPECT_NEAR(s.reflected_radiance[i] / expect, 1.0, 1e-3) << "mu " << s.mu[i];
    }
}

}  // namespace
}  // namespace nimbus::test
