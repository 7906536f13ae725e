// Test fixture of the DOM verification tests: a scene with a homogeneous medium (or a given
// density), a collimated sun whose optical depth is computed analytically, and the solve
// context, on a given communicator.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "solvers/dom/dom.h"
#include "src/core/error.h"
#include "src/core/gather.h"
#include "src/core/halo.h"
#include "src/model/model.h"

namespace nimbus::test {

struct DomWorld {
    Scene scene;
    Decomposition d;
    Medium m;
    LightTransport light;
    Report report;
    // Homogeneous density rho in a box of n cells of edge h (all cells full).
    DomWorld(MPI_Comm comm, const Int3& n, double h, BandOptics optics, std::array<bool, 3> periodic = {false, false, false})
        : d(comm, n, {0, 0, 0}, periodic) {
        scene.grid.n = n;
        scene.grid.periodic = periodic;
        m.grid.n = n;
        m.grid.h = h;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) { m.rho(i, j, k) = 1.0; });
        m.bands = {optics};
    }
    // A sun of irradiance E0 travelling along w (w.z < 0) into a medium that is homogeneous in
    // layers: tau_rho = (h / |w_z|) (rho / 2 + the sum of rho over the cells above it in its
    // column), the optical depth along -w from the cell centre to the top plane. Collective (the
    // density is gathered); call it once rho is final. It used rho of the cell itself for the
    // whole way up until the fiftieth session, which put no light into a layer under empty ones
    // and none lost above empty ones: the first-scatter cut (FirstScatterMeans) then zeroed the
    // source of the periodic slab tests (their layers of medium lie between empty ones), and
    // those tests passed without any light.
    void add_sun_from_top(const Vec3& w, double E0 = 1.0) {
        const Vec3 u = normalized(w);
        light.lights.push_back(DirectionalLight{"sun", u, {E0}});
        const std::vector<double> rho = allgather_global(m.rho, d);
        const Int3 n = m.grid.n;
        const auto at = [&](int i, int j, int k) {
            return rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i];
        };
        Field<double> tau(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            double column = 0.5 * at(i, j, k);
            for (int q = k + 1; q < n[2]; ++q) column += at(i, j, q);
            tau(i, j, k) = column * m.grid.h / std::abs(u.z);
        });
        exchange_halo(tau, d);  // the light pass's contract: ghosts exchanged
        light.tau_rho.push_back(std::move(tau));
    }
    // Collective: exchanges rho's ghost layer first (the Medium's contract, which the cell means
    // of T rely on at a rank's faces; the tests set rho on the owned cells only).
    SolveContext ctx() {
        exchange_halo(m.rho, d);
        return {scene, d, m, light, report};
    }
};

// Decomposition-invariance check: the largest |a - b| of band 0's fluence and flux over the
// cells of d (max over d.comm()), and the peak of b's fluence. Collective over d.comm().
struct SolutionDifference {
    double diff = 0.0, peak = 0.0;
};
inline SolutionDifference solution_difference(const Decomposition& d, const DiffuseSolution& a,
                                              const DiffuseSolution& b) {
    SolutionDifference r;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        r.diff = std::max(r.diff, std::abs(a.fluence[0](i, j, k) - b.fluence[0](i, j, k)));
        for (int c = 0; c < 3; ++c) r.diff = std::max(r.diff, std::abs(a.flux[0](i, j, k, c) - b.flux[0](i, j, k, c)));
        r.peak = std::max(r.peak, b.fluence[0](i, j, k));
    });
    MPI_Allreduce(MPI_IN_PLACE, &r.diff, 1, MPI_DOUBLE, MPI_MAX, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &r.peak, 1, MPI_DOUBLE, MPI_MAX, d.comm());
    return r;
}

// The thick cube of the iteration and scheme tests: n³ cells of optical thickness tau along each
// axis, isotropic scattering with albedo a, S4, a sun from the top, solved with `scheme` and
// `method` (DomOptions::iteration) to 1e-6 in at most max_iterations. A solve that throws is
// recorded, not rethrown (converged false, error = its message); the iteration history comes
// from the report either way. seconds: the solve, max over ranks. Collective.
struct CubeRun {
    bool converged = false;
    int iterations = 0;
    std::vector<double> history;
    int dsa_linear_iterations = 0;
    double seconds = 0.0;
    std::string error;
    DiffuseSolution sol;
};
inline CubeRun solve_thick_cube(int n, double tau, double albedo, const std::string& scheme,
                                const std::string& method, int max_iterations, double g = 0.0,
                                int legendre_order = 0) {
    DomWorld w(MPI_COMM_WORLD, {n, n, n}, tau / n, BandOptics{"gray", 1.0, albedo, g});
    w.add_sun_from_top({0.3, 0.2, -1.0});
    DomOptions o;
    o.order = 4;
    o.legendre_order = legendre_order;
    o.iteration = method;
    o.scheme = scheme;
    o.tolerance = 1e-6;
    o.max_iterations = max_iterations;
    CubeRun r;
    MPI_Barrier(MPI_COMM_WORLD);
    const double t0 = MPI_Wtime();
    try {
        make_dom_model(o)->solve(w.ctx(), r.sol);
        r.converged = true;
    } catch (const Error& e) {
        r.error = e.what();
    }
    r.seconds = MPI_Wtime() - t0;
    MPI_Allreduce(MPI_IN_PLACE, &r.seconds, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    const auto& band = w.report.values()["dom"]["solves"];
    if (!band.empty()) {
        r.iterations = band[0]["iterations"].get<int>();
        r.history = band[0]["history"].get<std::vector<double>>();
        if (band[0].contains("dsa_linear_iterations"))
            r.dsa_linear_iterations = band[0]["dsa_linear_iterations"].get<int>();
    }
    return r;
}

}  // namespace nimbus::test
