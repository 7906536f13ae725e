// Helpers for the diffusion verification tests: problems from analytic coefficient functions,
// small media lit by a vertical or oblique sun with exact optical depths, error norms.
#pragma once

#include <mpi.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "solvers/diffusion/diffusion_problem.h"
#include "src/core/decomposition.h"
#include "src/core/halo.h"
#include "src/model/model.h"
#include "src/scene/medium.h"

namespace nimbus::test {

using Fn = std::function<double(double, double, double)>;
using VecFn = std::function<Vec3(double, double, double)>;

// A DiffusionProblem with one rhs from functions of the cell-centre position (metres, origin 0).
inline diffusion::DiffusionProblem make_problem(const Decomposition& d, double h, const Fn& kappa_tr,
                                                const Fn& sigma_a, const Fn& Q0, const VecFn& G,
                                                std::array<bool, 3> periodic = {false, false, false}) {
    diffusion::DiffusionProblem p;
    p.h = h;
    p.n = d.global().hi;
    p.periodic = periodic;
    p.kappa_tr = Field<double>(d.local(), 1, 1, 0.0);
    p.sigma_a = Field<double>(d.local(), 0, 1, 0.0);
    Field<double> q0(d.local(), 0, 1, 0.0), g(d.local(), 1, 3, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double x = (i + 0.5) * h, y = (j + 0.5) * h, z = (k + 0.5) * h;
        p.kappa_tr(i, j, k) = kappa_tr(x, y, z);
        p.sigma_a(i, j, k) = sigma_a(x, y, z);
        q0(i, j, k) = Q0(x, y, z);
        const Vec3 v = G(x, y, z);
        for (int c = 0; c < 3; ++c) g(i, j, k, c) = v[c];
    });
    exchange_halo(p.kappa_tr, d);
    exchange_halo(g, d);
    p.Q0.push_back(std::move(q0));
    p.G.push_back(std::move(g));
    return p;
}

// Global max over ranks.
inline double global_max(double v, MPI_Comm comm) {
    double g = 0;
    MPI_Allreduce(&v, &g, 1, MPI_DOUBLE, MPI_MAX, comm);
    return g;
}
inline double global_sum(double v, MPI_Comm comm) {
    double g = 0;
    MPI_Allreduce(&v, &g, 1, MPI_DOUBLE, MPI_SUM, comm);
    return g;
}
inline double global_min(double v, MPI_Comm comm) {
    double g = 0;
    MPI_Allreduce(&v, &g, 1, MPI_DOUBLE, MPI_MIN, comm);
    return g;
}

// A medium of one band on d with density rho_fn(i, j, k) (a pure function of the global cell).
inline Medium make_medium(const Decomposition& d, double h, const BandOptics& band,
                          const std::function<double(int, int, int)>& rho_fn) {
    Medium m;
    m.grid.n = d.global().hi;
    m.grid.h = h;
    m.rho = Field<double>(d.local(), 1, 1, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) { m.rho(i, j, k) = rho_fn(i, j, k); });
    exchange_halo(m.rho, d);
    m.bands = {band};
    return m;
}

// Light transport of one sun along w with the optical depth from each cell centre back to the
// top of the domain, exact for media that are uniform in x and y or for a vertical sun
// (w = (0, 0, -1)): tau = ∫ rho ds along the column above, divided by |w_z|.
inline LightTransport column_light(const Decomposition& d, double h, const Vec3& w, double E0,
                                   const std::function<double(int, int, int)>& rho_fn) {
    LightTransport lt;
    lt.lights = {DirectionalLight{"sun", w, {E0}}};
    Field<double> tau(d.local(), 1, 1, 0.0);
    const int nz = d.global().hi[2];
    for_each_cell(d.local(), [&](int i, int j, int k) {
        double s = 0.5 * rho_fn(i, j, k);
        for (int kk = k + 1; kk < nz; ++kk) s += rho_fn(i, j, kk);
        tau(i, j, k) = s * h / std::abs(w.z);
    });
    exchange_halo(tau, d);
    lt.tau_rho.push_back(std::move(tau));
    return lt;
}

}  // namespace nimbus::test

namespace nimbus::test {

// Runs a ScatteringModel on a one-band medium lit by one sun (column_light) and returns the
// solution; report receives the model's values.
template <class Model>
DiffuseSolution run_model(Model& model, const Decomposition& d, double h, const BandOptics& band,
                          const std::function<double(int, int, int)>& rho_fn, const Vec3& w,
                          Report& report, double E0 = 1.0) {
    Medium m = make_medium(d, h, band, rho_fn);
    LightTransport light = column_light(d, h, w, E0, rho_fn);
    Scene scene;
    SolveContext ctx{scene, d, m, light, report};
    DiffuseSolution sol;
    model.solve(ctx, sol);
    return sol;
}

// Max |a - b| over d.local() of band 0 fluence, and max |a| (both global).
inline std::pair<double, double> max_diff(const Field<double>& a, const Field<double>& b, const Box& box,
                                          MPI_Comm comm) {
    double diff = 0.0, amax = 0.0;
    for_each_cell(box, [&](int i, int j, int k) {
        diff = std::max(diff, std::abs(a(i, j, k) - b(i, j, k)));
        amax = std::max(amax, std::abs(a(i, j, k)));
    });
    return {global_max(diff, comm), global_max(amax, comm)};
}

}  // namespace nimbus::test
