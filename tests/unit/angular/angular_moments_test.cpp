// Angular moments (src/physics/angular_moments): HG Legendre coefficients and delta-M, real
// spherical harmonics against closed forms, orthonormality, the addition theorem, and the
// discrete-to-moment / moment-to-discrete scattering operator on every quadrature.
#include "src/physics/angular_moments.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "src/core/error.h"
#include "src/physics/phase.h"

namespace nimbus {
namespace {

constexpr double kPi = std::numbers::pi;

// Every quadrature kind (each knows its exact_degree, checked in quadrature_test.cpp).
std::vector<Quadrature> all_quadratures() {
    std::vector<Quadrature> qs;
    for (int N = 2; N <= 16; N += 2) qs.push_back(level_symmetric(N));
    qs.push_back(product_quadrature(4, 8));
    qs.push_back(product_quadrature(8, 16));
    qs.push_back(cube_face_bins(4));
    return qs;
}

Vec3 random_direction(std::mt19937_64& rng) {
    std::normal_distribution<double> n;
    return normalized(Vec3{n(rng), n(rng), n(rng)});
}

TEST(HgLegendre, PlainCoefficientsArePowersOfG) {
    for (double g : {-0.4, 0.0, 0.3, 0.85}) {
        const LegendrePhase p = hg_legendre(g, 12, false);
        EXPECT_EQ(p.f, 0.0);
        ASSERT_EQ(p.chi.size(), 13u);
        for (int l = 0; l <= 12; ++l) EXPECT_NEAR(p.chi[l], std::pow(g, l), 1e-15) << g << " " << l;
    }
}

TEST(HgLegendre, SeriesConvergesToHgPhaseFunction) {
    // Σ_l (2l+1)/(4π) g^l P_l(mu) is the generating function of HG: an independent check of the
    // normalization (∫ p dΩ = 1, DESIGN §1). Truncation error ~ g^{L+1}.
    const LegendrePhase p = hg_legendre(0.5, 80, false);
    for (double mu = -1; mu <= 1.0; mu += 0.05)
        EXPECT_NEAR(legendre_phase_value(p, mu), hg_phase(0.5, mu), 1e-12 * hg_phase(0.5, 1.0))
            << mu;
}

TEST(HgLegendre, DeltaMScaling) {
    for (double g : {0.3, 0.85, 0.95})
        for (int L : {0, 1, 4, 8, 16}) {
            const LegendrePhase p = hg_legendre(g, L, true);
            const double f = std::pow(g, L + 1);
            EXPECT_NEAR(p.f, f, 1e-15);
            EXPECT_NEAR(p.chi[0], 1.0, 1e-15);
            if (L >= 1) {
                EXPECT_NEAR(p.chi[1], (g - f) / (1 - f), 1e-14);
            }
            // f δ(forward) + (1-f) p* reproduces the HG moments 0..L (Wiscombe 1977 eq. 9).
            for (int l = 0; l <= L; ++l) EXPECT_NEAR(f + (1 - f) * p.chi[l], std::pow(g, l), 1e-14);
        }
    // Medium scaling: extinction of the scattering part removed, absorption kept.
    const double a = 0.9, f = 0.3;
    const double st = delta_m_sigma_t_scale(a, f), as = delta_m_albedo(a, f);
    EXPECT_NEAR(st * (1 - as), 1 - a, 1e-15);  // sigma_a* = sigma_a
    EXPECT_NEAR(st * as, a * (1 - f), 1e-15);  // sigma_s* = (1-f) sigma_s
    EXPECT_THROW(hg_legendre(1.0, 4, true), Error);
    EXPECT_THROW(hg_legendre(0.5, -1, true), Error);
}

TEST(RealSphericalHarmonics, ClosedFormsWithoutCondonShortleyPhase) {
    std::mt19937_64 rng(7);
    for (int t = 0; t < 50; ++t) {
        const Vec3 d = random_direction(rng);
        const double x = d.x, y = d.y, z = d.z;
        std::vector<double> Y;
        real_spherical_harmonics(3, d, Y);
        ASSERT_EQ(Y.size(), 16u);
        const double c1 = std::sqrt(3 / (4 * kPi)), c2 = std::sqrt(15 / (4 * kPi));
        const std::vector<double> ref = {
            1 / std::sqrt(4 * kPi),
            c1 * y,
            c1 * z,
            c1 * x,  // l = 1: m = -1, 0, 1
            c2 * x * y,
            c2 * y * z,
            std::sqrt(5 / (16 * kPi)) * (3 * z * z - 1),
            c2 * x * z,
            0.5 * c2 * (x * x - y * y),                            // l = 2
            std::sqrt(35 / (32 * kPi)) * y * (3 * x * x - y * y),  // l = 3, m = -3
            std::sqrt(105 / (4 * kPi)) * x * y * z,
            std::sqrt(21 / (32 * kPi)) * y * (5 * z * z - 1),
            std::sqrt(7 / (16 * kPi)) * z * (5 * z * z - 3),
            std::sqrt(21 / (32 * kPi)) * x * (5 * z * z - 1),
            std::sqrt(105 / (16 * kPi)) * z * (x * x - y * y),
            std::sqrt(35 / (32 * kPi)) * x * (x * x - 3 * y * y)};
        for (int k = 0; k < 16; ++k) EXPECT_NEAR(Y[k], ref[k], 1e-14) << "k " << k;
    }
}

// DSA maps the l = 1 moments to the current's components and back through these two.
TEST(RealSphericalHarmonics, FirstMomentsAreTheCurrentsComponents) {
    std::mt19937_64 rng(5);
    for (int t = 0; t < 20; ++t) {
        const Vec3 d = random_direction(rng);
        std::vector<double> Y;
        real_spherical_harmonics(1, d, Y);
        for (int k = 1; k <= 3; ++k)
            EXPECT_NEAR(Y[k], first_moment_scale() * d[first_moment_axis(k)], 1e-15) << "k " << k;
    }
}

TEST(RealSphericalHarmonics, OrthonormalOnFineProductQuadrature) {
    const int L = 12;
    const Quadrature q = product_quadrature(16, 32);  // exact for degree <= 24 < 2·16, m < 32
    const MomentOperator op = make_moment_operator(q, L);
    double err = 0;
    for (int a = 0; a < op.nmom; ++a)
        for (int b = 0; b < op.nmom; ++b) {
            double s = 0;
            for (int n = 0; n < q.size(); ++n)
                s += q.weight[n] * op.m2d[n * op.nmom + a] * op.m2d[n * op.nmom + b];
            err = std::max(err, std::abs(s - (a == b ? 1.0 : 0.0)));
        }
    std::printf("  orthonormality of Y_k, L = %d, product 16x32: max error %.1e\n", L, err);
    EXPECT_LT(err, 1e-13);
}

TEST(RealSphericalHarmonics, AdditionTheorem) {
    std::mt19937_64 rng(11);
    const int L = 16;
    std::vector<double> Ya, Yb, P;
    for (int t = 0; t < 30; ++t) {
        const Vec3 a = random_direction(rng), b = random_direction(rng);
        real_spherical_harmonics(L, a, Ya);
        real_spherical_harmonics(L, b, Yb);
        legendre_polynomials(L, dot(a, b), P);
        for (int l = 0; l <= L; ++l) {
            double s = 0;
            for (int m = -l; m <= l; ++m) s += Ya[l * l + l + m] * Yb[l * l + l + m];
            EXPECT_NEAR(s, (2 * l + 1) / (4 * kPi) * P[l], 1e-13) << "l " << l;
        }
    }
    // The poles: only m = 0 survives, no division by sin(theta).
    real_spherical_harmonics(L, Vec3{0, 0, -1}, Ya);
    for (int l = 0; l <= L; ++l)
        EXPECT_NEAR(Ya[l * l + l], std::sqrt((2 * l + 1) / (4 * kPi)) * (l % 2 ? -1 : 1), 1e-13);
}

TEST(MomentOperator, DiscreteToMomentInvertsMomentToDiscreteOnExactQuadrature) {
    const Quadrature q = product_quadrature(16, 32);
    const MomentOperator op = make_moment_operator(q, 8);
    ASSERT_EQ(op.nmom, 81);
    ASSERT_EQ(op.ndir, 512);
    double err = 0;
    for (int a = 0; a < op.nmom; ++a)
        for (int b = 0; b < op.nmom; ++b) {
            double s = 0;
            for (int n = 0; n < op.ndir; ++n)
                s += op.d2m[a * op.ndir + n] * op.m2d[n * op.nmom + b];
            err = std::max(err, std::abs(s - (a == b ? 1.0 : 0.0)));
        }
    EXPECT_LT(err, 1e-13);
    for (int k = 0; k < op.nmom; ++k) EXPECT_EQ(op.degree[k], static_cast<int>(std::sqrt(k + 0.5)));
}

TEST(MomentOperator, IsotropicFluxScattersToChi0) {
    const LegendrePhase p = hg_legendre(0.85, 16, true);
    std::printf(
        "  quadrature                                        L_exact  moment err at L_exact   at L "
        "= 8\n");
    for (const Quadrature& q : all_quadratures()) {
        const int L = q.exact_degree;  // Y_k with l <= L integrate exactly
        const MomentOperator op = make_moment_operator(q, L);
        std::vector<double> S;
        scatter_by_moments(op, p, std::vector<double>(q.size(), 1.0), S);
        double err = 0;
        for (double s : S) err = std::max(err, std::abs(s - p.chi[0]));
        EXPECT_LT(err, 1e-12) << q.name;
        const double e_exact = quadrature_moment_error(q, L), e8 = quadrature_moment_error(q, 8);
        // Absolute error of Σ w Y_k; Y_k of degree 15 has monomial coefficients ~1e3, so the
        // 1e-15 round-off of the weights shows up as ~1e-12 here.
        EXPECT_LT(e_exact, 1e-11) << q.name;
        std::printf("  %-50s %4d     %.1e                %.1e\n", q.name.c_str(), L, e_exact, e8);
    }
}

TEST(MomentOperator, DeltaScattersToTruncatedHgSeries) {
    // psi = δ_{n n0} / w_n0 (unit flux along Ω_n0): S(Ω_n) = Σ_l (2l+1)/(4π) chi_l P_l(Ω_n·Ω_n0)
    // by the addition theorem, for any quadrature.
    for (bool dm : {false, true}) {
        const LegendrePhase p = hg_legendre(0.8, 8, dm);
        for (const Quadrature& q : all_quadratures()) {
            const MomentOperator op = make_moment_operator(q, 8);
            for (int n0 : {0, q.size() / 3, q.size() - 1}) {
                std::vector<double> psi(q.size(), 0.0), S;
                psi[n0] = 1.0 / q.weight[n0];
                scatter_by_moments(op, p, psi, S);
                for (int n = 0; n < q.size(); ++n)
                    EXPECT_NEAR(S[n], legendre_phase_value(p, dot(q.dir[n], q.dir[n0])), 1e-12)
                        << q.name;
            }
        }
    }
}

TEST(MomentOperator, ConservativeVariantConservesOnAnyQuadrature) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    const LegendrePhase p = hg_legendre(0.85, 8, false);
    for (const Quadrature& q : all_quadratures()) {
        const MomentOperator op = make_moment_operator(q, 8, true);
        EXPECT_TRUE(op.conservative);
        std::vector<double> S;
        scatter_by_moments(op, p, std::vector<double>(q.size(), 1.0), S);
        for (double s : S) EXPECT_NEAR(s, 1.0, 1e-12) << q.name;
        std::vector<double> psi(q.size());
        for (double& v : psi) v = u(rng);
        scatter_by_moments(op, p, psi, S);
        double in = 0, out = 0;
        for (int n = 0; n < q.size(); ++n) in += q.weight[n] * psi[n], out += q.weight[n] * S[n];
        EXPECT_NEAR(out, in, 1e-12 * in) << q.name;
        // Symmetric kernel K_nn' / w_n' (reciprocity).
        const int a = 0, b = q.size() / 2 + 1;
        std::vector<double> ea(q.size(), 0.0), eb(q.size(), 0.0), Sa, Sb;
        ea[a] = 1 / q.weight[a];
        eb[b] = 1 / q.weight[b];
        scatter_by_moments(op, p, ea, Sa);
        scatter_by_moments(op, p, eb, Sb);
        EXPECT_NEAR(Sa[b], Sb[a], 1e-12) << q.name;
    }
    // Identical to the plain operator on a quadrature that is exact to L.
    const Quadrature q = product_quadrature(8, 16);
    const MomentOperator plain = make_moment_operator(q, 8),
                         cons = make_moment_operator(q, 8, true);
    for (std::size_t i = 0; i < plain.m2d.size(); ++i)
        EXPECT_NEAR(plain.m2d[i], cons.m2d[i], 1e-14);
}

}  // namespace
}  // namespace nimbus
