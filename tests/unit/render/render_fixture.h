// Test scaffolding for the ray caster: a medium, light transport and diffuse field built
// directly from pure functions of the global cell index (so every decomposition, and the
// ghost layers, see the same values), plus an independent ray/box chord and image access.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/halo.h"
#include "src/model/model.h"
#include "src/render/camera.h"
#include "src/render/raycaster.h"
#include "src/scene/medium.h"
#include "src/scene/scene.h"

namespace nimbus::test {

// Everything render_image reads, on one decomposition.
struct RenderWorld {
    std::unique_ptr<Decomposition> d;
    Medium medium;
    LightTransport light;
    DiffuseSolution diffuse;
};

inline bool inside_domain(const Int3& n, int i, int j, int k) {
    return i >= 0 && j >= 0 && k >= 0 && i < n[0] && j < n[1] && k < n[2];
}

// Owned cells from f, ghosts inside the domain by halo exchange, ghosts outside from f too
// (the caller's boundary condition: return 0 there for the usual empty outside).
template <class Fn>
Field<double> make_field(const Decomposition& d, Fn&& f, int ncomp = 1) {
    Field<double> out(d.local(), 1, ncomp, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        for (int c = 0; c < ncomp; ++c) out(i, j, k, c) = f(i, j, k, c);
    });
    exchange_halo(out, d);
    const Int3 n = d.global().hi;
    for_each_cell(out.allocated(), [&](int i, int j, int k) {
        if (!inside_domain(n, i, j, k))
            for (int c = 0; c < ncomp; ++c) out(i, j, k, c) = f(i, j, k, c);
    });
    return out;
}

// rho(i, j, k) on grid g, bands from the scene; no lights, zero diffuse field.
// periodic: the decomposition's periodic axes (rho must then be periodic along them too).
template <class Rho>
RenderWorld make_world(MPI_Comm comm, const Grid& g, const Scene& scene, Rho&& rho,
                       const Int3& proc_dims = {0, 0, 0}, std::array<bool, 3> periodic = {false, false, false}) {
    RenderWorld w;
    w.d = std::make_unique<Decomposition>(comm, g.n, proc_dims, periodic);
    w.medium.grid = g;
    w.medium.bands = scene.bands;
    w.medium.rho = make_field(*w.d, [&](int i, int j, int k, int) { return rho(i, j, k); });
    w.diffuse = zero_solution(*w.d, scene.nbands());
    return w;
}

// The 32 x 24 oblique view of the unit-ish test domains: from (1.6, -0.7, 1.4) (domain
// fractions) towards the centre, so rays cross every slab boundary.
inline void oblique_camera(Scene& s) {
    s.camera.position = {1.6, -0.7, 1.4};
    s.camera.look_at = {0.5, 0.5, 0.5};
    s.camera.fov_deg = 55;
    s.camera.width = 32;
    s.camera.height = 24;
}

inline Image render(const Scene& scene, const RenderWorld& w) {
    Report report;
    return render_image(RenderInputs{scene, w.medium, w.light, w.diffuse}, *w.d, report);
}

// Chord [t_in, t_out] of the ray o + t d (t >= 0) through the box [lo, hi]; false if none.
inline bool chord(const Vec3& o, const Vec3& d, const Vec3& lo, const Vec3& hi, double& t_in,
                  double& t_out) {
    t_in = 0.0;
    t_out = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (o[a] < lo[a] || o[a] > hi[a]) return false;
            continue;
        }
        const double t1 = (lo[a] - o[a]) / d[a], t2 = (hi[a] - o[a]) / d[a];
        t_in = std::max(t_in, std::min(t1, t2));
        t_out = std::min(t_out, std::max(t1, t2));
    }
    return t_out > t_in;
}

// |a - b| <= rel |b| (plus a denormal-sized floor for exact zeros).
inline bool close_rel(double a, double b, double rel) {
    return std::abs(a - b) <= rel * std::abs(b) + 1e-30;
}

}  // namespace nimbus::test
