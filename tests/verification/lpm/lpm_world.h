// Test scaffolding for the LPM tests: a decomposition, a medium given by a density function,
// and the light pass for a list of directional lights (compute_light_transport, exact method).
#pragma once

#include <functional>
#include <vector>

#include "solvers/light/sun_transmittance.h"
#include "solvers/lpm/solve_band.h"
#include "src/core/halo.h"
#include "src/model/model.h"

namespace nimbus::test {

struct LpmWorld {
    Scene scene;
    Decomposition d;
    Medium m;
    LightTransport light;
    Report report;

    LpmWorld(MPI_Comm comm, Int3 n, std::array<bool, 3> periodic, const std::function<double(int, int, int)>& rho,
             BandOptics band, std::vector<DirectionalLight> lights)
        : d(comm, n, {0, 0, 0}, periodic) {
        scene.grid.n = n;
        scene.grid.periodic = periodic;
        m.grid.n = n;
        m.grid.h = 1.0;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) { m.rho(i, j, k) = rho(i, j, k); });
        exchange_halo(m.rho, d);
        m.bands = {band};
        light = compute_light_transport(d, m, lights, report, {}, LightSpec::Method::exact);
    }
    SolveContext ctx() { return {scene, d, m, light, report}; }
    lpm::BandResult solve(const LpmOptions& o) const {
        const lpm::Angular a(o.p, o.k);
        return lpm::solve_band(d, m, light, 0, o, a);
    }
    // Σ over owned cells of f(i, j, k), over all ranks.
    template <class Fn>
    double sum(Fn&& f) const {
        double s = 0.0;
        for_each_cell(d.local(), [&](int i, int j, int k) { s += f(i, j, k); });
        MPI_Allreduce(MPI_IN_PLACE, &s, 1, MPI_DOUBLE, MPI_SUM, d.comm());
        return s;
    }
};

inline LpmOptions lpm_options(int p, int k, int iterations, double epsilon = 0.0, int refinement = 1) {
    LpmOptions o;
    o.p = p;
    o.k = k;
    o.iterations = iterations;
    o.epsilon = epsilon;
    o.refinement = refinement;
    o.tail = "none";  // the map iteration alone; the tails are tested in tail_test.cpp
    return o;
}

}  // namespace nimbus::test
