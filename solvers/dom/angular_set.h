// The quadrature and moment operator of a DOM run, regrouped by octant for the sweeps.
// Band-independent; built once per model run. Pure values, no MPI; the caller owns it.
//
// For octant o with directions n (in octant order) the sweeps need, contiguous in n:
//   abs_mu[a][n] = |Ω_a,n|              (the step/diamond kernels divide by h themselves)
//   Y[k][n]      = Y_k(Ω_n)             moment-to-discrete, k = 0..nmom-1 (moment-major)
//   wY[k][n]     = w_n Y_k(Ω_n)         discrete-to-moment
// with the real orthonormal harmonics of src/physics/angular_moments.h, so that the scattering
// source is S(Ω_n) = Σ_k Y_k(Ω_n) chi_{l(k)} phi_k and phi_k = Σ_n w_n Y_k(Ω_n) psi_n.
#pragma once

#include <array>
#include <vector>

#include "solvers/sweep/order.h"
#include "src/model/options.h"
#include "src/physics/angular_moments.h"
#include "src/physics/quadrature.h"

namespace nimbus::dom {

struct OctantDirections {
    sweep::Octant octant;
    std::vector<int> index;                   // quadrature index of each direction
    std::array<std::vector<double>, 3> abs_mu;  // |Ω_a| per direction
    std::vector<double> weight;               // w_n (sr)
    std::vector<Vec3> dir;
    std::vector<double> Y;                    // nmom x nd
    std::vector<double> wY;                   // nmom x nd
    int size() const { return static_cast<int>(index.size()); }
};

struct AngularSet {
    Quadrature quadrature;
    int L = 0, nmom = 1;
    std::vector<int> degree;                  // l of each moment
    std::array<OctantDirections, 8> octants;
    int max_octant_size = 0;
};

// Throws Error for an invalid quadrature. Directions with a zero component belong to the
// octant with + sign there (their |Ω_a| = 0 couples nothing along that axis).
AngularSet make_angular_set(const Quadrature& q, int L);
AngularSet make_angular_set(const DomOptions& opt);

}  // namespace nimbus::dom
