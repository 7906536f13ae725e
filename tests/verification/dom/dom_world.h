// Test fixture of the DOM verification tests: a scene with a homogeneous medium (or a given
// density), a collimated sun whose optical depth is computed analytically, and the solve
// context, on a given communicator.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <cmath>

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
    // layers: tau_rho = (distance along -w from the cell centre to the top plane) x rho.
    void add_sun_from_top(const Vec3& w, double E0 = 1.0) {
        const Vec3 u = normalized(w);
        light.lights.push_back(DirectionalLight{"sun", u, {E0}});
        Field<double> tau(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            tau(i, j, k) = (m.grid.n[2] - k - 0.5) * m.grid.h / std::abs(u.z) * m.rho(i, j, k);
        });
        light.tau_rho.push_back(std::move(tau));
    }
    SolveContext ctx() { return {scene, d, m, light, report}; }
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

}  // namespace nimbus::test
