// Independent 1-D reference for the Monte Carlo verification tests (test support, not product
// code): diffuse light in a homogeneous plane-parallel slab of optical thickness tau0, albedo
// a and Henyey-Greenstein asymmetry g, lit from above by a collimated beam of irradiance E0 = 1
// (on a plane normal to the beam) at polar cosine mu0.
//
// Method: discrete ordinates with double-Gauss directions (N per hemisphere, weights c_i with
// sum 1), azimuthally averaged HG kernel from its Legendre expansion
//   P(mu, mu') = sum_{l=0}^{L} (2l+1) g^l P_l(mu) P_l(mu'),   g^L < 1e-8, L <= 2N - 1
// (so the quadrature integrates every row of P exactly and scattering conserves energy), and
// the doubling-adding method (van de Hulst 1980; Wiscombe 1976): a thin layer of thickness
// tau0 / 2^n from exact single scattering, doubled to tau0. Direct and diffuse transmission are
// kept apart so no small quantity is formed as a difference. The beam enters as the source
//   J(tau, ±mu_i) = a / (4π) P(±mu_i, mu0) exp(-tau / mu0).
// Interior fields come from adding the layers above and below a level.
#pragma once

#include <vector>

namespace nimbus::test {

struct SlabProblem {
    double tau0 = 1.0;    // optical thickness
    double albedo = 0.9;  // single-scattering albedo
    double g = 0.0;       // HG asymmetry
    double mu0 = 1.0;     // cosine of the beam's angle to the downward normal, (0, 1]
    int n_half = 0;       // directions per hemisphere; 0 = max(32, enough for the Legendre order)
    double thin = 1e-10;  // largest optical thickness of the initial (single-scatter) layer
    int profile_levels = 0;  // 0, or a power of 2: fluence at tau_k = k tau0 / levels, k = 0..levels
};

struct SlabSolution {
    double reflected = 0.0;             // diffuse flux out of the top / incident flux (E0 mu0)
    double transmitted_diffuse = 0.0;   // diffuse flux out of the bottom / incident flux
    double transmitted_direct = 0.0;    // exp(-tau0 / mu0)
    std::vector<double> mu, weight;     // quadrature: mu_i in (0, 1), weights summing to 1
    std::vector<double> reflected_radiance;  // upward diffuse radiance at the top at mu_i (per E0)
    std::vector<double> tau;             // profile levels
    std::vector<double> fluence;         // diffuse fluence ∫ I_d dw at tau (per unit E0)
    int legendre_order = 0;
};

SlabSolution solve_slab(const SlabProblem& p);

// Gauss-Legendre nodes and weights on [a, b].
void gauss_legendre(int n, double a, double b, std::vector<double>& x, std::vector<double>& w);

}  // namespace nimbus::test
