#include "src/render/ground.h"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "src/core/error.h"
#include "src/physics/lights.h"

namespace nimbus {

namespace {

using OuterLayers = GroundShading::OuterLayers;

// The outer cell layers of f, the same on every rank: each rank fills the cells it owns, the
// sum over ranks assembles them. Collective over comm (one field's values: < 2^31).
OuterLayers gather_outer_layers(const Field<double>& f, const Box& owned, const Int3& n, MPI_Comm comm) {
    OuterLayers out;
    out.bottom.assign(static_cast<size_t>(n[0]) * static_cast<size_t>(n[1]), 0.0);
    if (owned.lo[2] == 0)
        for (int j = owned.lo[1]; j < owned.hi[1]; ++j)
            for (int i = owned.lo[0]; i < owned.hi[0]; ++i)
                out.bottom[static_cast<size_t>(j) * static_cast<size_t>(n[0]) + static_cast<size_t>(i)] = f(i, j, 0);
    for (int face = 0; face < 4; ++face) {
        const int axis = face / 2, nt = n[1 - axis];
        std::vector<double>& side = out.side[static_cast<size_t>(face)];
        side.assign(static_cast<size_t>(nt) * static_cast<size_t>(n[2]), 0.0);
        const int c = face % 2 == 0 ? 0 : n[axis] - 1;  // the face's cell layer
        if (c < owned.lo[axis] || c >= owned.hi[axis]) continue;
        for (int k = owned.lo[2]; k < owned.hi[2]; ++k)
            for (int t = owned.lo[1 - axis]; t < owned.hi[1 - axis]; ++t)
                side[static_cast<size_t>(k) * static_cast<size_t>(nt) + static_cast<size_t>(t)] =
                    axis == 0 ? f(c, t, k) : f(t, c, k);
    }
    std::vector<double> all(out.bottom);
    for (const auto& side : out.side) all.insert(all.end(), side.begin(), side.end());
    MPI_Allreduce(MPI_IN_PLACE, all.data(), static_cast<int>(all.size()), MPI_DOUBLE, MPI_SUM, comm);
    auto at = all.begin();
    for (std::vector<double>* part : {&out.bottom, &out.side[0], &out.side[1], &out.side[2], &out.side[3]}) {
        std::copy(at, at + static_cast<std::ptrdiff_t>(part->size()), part->begin());
        at += static_cast<std::ptrdiff_t>(part->size());
    }
    return out;
}

// A layer of na x nb unit cells holding v[b * na + a] for cell (a, b), wrapped along its
// periodic axes and clamped to its cells otherwise.
struct Layer {
    const std::vector<double>& v;
    int na, nb;
    bool periodic_a, periodic_b;

    static int wrap(int i, int n, bool periodic) {
        return periodic ? ((i % n) + n) % n : std::clamp(i, 0, n - 1);
    }
    double at(int a, int b) const {
        return v[static_cast<size_t>(wrap(b, nb, periodic_b)) * static_cast<size_t>(na) +
                 static_cast<size_t>(wrap(a, na, periodic_a))];
    }

    // Bilinear between the cells' centres at point (pa, pb) (cell units).
    double bilinear_centres(double pa, double pb) const {
        auto corner = [](double p, int n, bool periodic, int& i0, double& f) {
            const double c = periodic ? p - 0.5 : std::clamp(p - 0.5, 0.0, n - 1.0);
            i0 = static_cast<int>(std::floor(c));
            f = c - i0;
        };
        int a0 = 0, b0 = 0;
        double fa = 0, fb = 0;
        corner(pa, na, periodic_a, a0, fa);
        corner(pb, nb, periodic_b, b0, fb);
        return (1 - fb) * ((1 - fa) * at(a0, b0) + fa * at(a0 + 1, b0)) +
               fb * ((1 - fa) * at(a0, b0 + 1) + fa * at(a0 + 1, b0 + 1));
    }

    // ∫_0^S v(a0 + s da, b0 + s db) ds over the piecewise-constant cells: exact, cell by cell
    // (s in cells along a unit 3D direction whose components in the layer are da, db).
    double segment_integral(double a0, double b0, double da, double db, double S) const {
        constexpr double kInf = std::numeric_limits<double>::infinity();
        auto to_next_line = [&](double x, double dx) {
            return dx > 0 ? (std::floor(x) + 1 - x) / dx : dx < 0 ? (x - (std::ceil(x) - 1)) / -dx : kInf;
        };
        const double min_step = 1e-12 * std::max(1.0, S);  // no stall on a line hit by round-off
        double sum = 0, s = 0;
        while (s < S) {
            const double a = a0 + s * da, b = b0 + s * db;
            const double ds = std::min(S - s, std::max(min_step, std::min(to_next_line(a, da), to_next_line(b, db))));
            const double sm = s + 0.5 * ds;  // the piece's midpoint names its cell
            sum += ds * at(static_cast<int>(std::floor(a0 + sm * da)), static_cast<int>(std::floor(b0 + sm * db)));
            s += ds;
        }
        return sum;
    }
};

}  // namespace

double GroundShading::outer_layer_values(const Int3& n) {
    return static_cast<double>(n[0]) * n[1] + 2.0 * (static_cast<double>(n[0]) + n[1]) * n[2];
}

GroundShading::GroundShading(const RenderInputs& in, const Decomposition& d)
    : in_(in), owned_(d.local()) {
    const BackgroundSpec& bg = in.scene.background;
    if (bg.kind != BackgroundSpec::Kind::ground) return;
    const int nb = in.medium.nbands();
    for (int b = 0; b < nb; ++b)
        albedo_.push_back(bg.ground_color.empty() ? bg.ground_albedo : band_value(bg.ground_color, b));
    shadows_ = in.scene.render.mode != RenderMode::single_unshadowed;
    // Checked collectively: the gathers below must be reached by every rank or by none (a
    // throw on one rank would leave the others in them).
    std::string problem;
    if (shadows_ && in.light.tau_rho.size() != in.light.lights.size())
        problem = "render: the ground background needs tau_rho from the light pass for every light";
    if (shadows_ && problem.empty())
        for (const auto& f : in.light.tau_rho)
            if (f.allocated().intersect(d.local().grown(1)) != d.local().grown(1))
                problem = "render: tau_rho must cover the rank's box plus 1 ghost layer";
    check_collective(d.comm(), problem.empty(), problem);
    active_ = d.at_low_boundary(2);
    periodic_ = {d.periodic(0), d.periodic(1)};
    if (!shadows_) return;
    const Int3& n = in.medium.grid.n;
    rho_ = gather_outer_layers(in.medium.rho, owned_, n, d.comm());
    for (const auto& tau : in.light.tau_rho) {
        OuterLayers layers = gather_outer_layers(tau, owned_, n, d.comm());
        if (active_) tau_.push_back(std::move(layers));  // only the ranks with a part of the bottom shade
    }
    if (!active_) rho_ = OuterLayers{};
}

double GroundShading::ground_tau(size_t l, double qx, double qy) const {
    const Int3& n = in_.medium.grid.n;
    const Vec3 u = -in_.light.lights[l].w;  // toward the light, u.z > 0
    const double q[2] = {qx, qy}, ud[2] = {u.x, u.y};
    // The ray q + s u (s >= 0, cells) in the box [0, nx] x [0, ny] x [0, nz] (unbounded along
    // periodic axes): entered at s0 (0 in the footprint, else through side face `face`), left
    // at s1.
    double s0 = 0.0, s1 = n[2] / u.z;
    int face = -1;
    for (int a = 0; a < 2; ++a) {
        if (periodic_[a]) continue;
        if (ud[a] == 0.0) {
            if (q[a] < 0.0 || q[a] > n[a]) return 0.0;  // beside the domain, parallel to it
            continue;
        }
        const double s_lo = (0.0 - q[a]) / ud[a], s_hi = (n[a] - q[a]) / ud[a];
        const double enter = std::min(s_lo, s_hi), leave = std::max(s_lo, s_hi);
        if (enter > s0) s0 = enter, face = 2 * a + (ud[a] > 0.0 ? 0 : 1);
        s1 = std::min(s1, leave);
    }
    if (!(s0 < s1)) return 0.0;  // misses the domain
    const double e[3] = {qx + s0 * u.x, qy + s0 * u.y, s0 * u.z};
    const double h = in_.medium.grid.h;
    const OuterLayers& tau = tau_[l];
    if (e[2] < 0.5) {
        // Through the bottom layer's lower half up to its centres' height (or out of the domain).
        const Layer rho{rho_.bottom, n[0], n[1], periodic_[0], periodic_[1]};
        const double s_half = 0.5 / u.z;
        double t = h * rho.segment_integral(e[0], e[1], u.x, u.y, std::min(s_half, s1) - s0);
        if (s_half < s1)
            t += Layer{tau.bottom, n[0], n[1], periodic_[0], periodic_[1]}.bilinear_centres(qx + s_half * u.x,
                                                                                          qy + s_half * u.y);
        return t;
    }
    // Through side face `face`'s outer half cell to its centre plane, h/2 in (or out of the domain).
    const int axis = face / 2, ta = 1 - axis;
    const double s_centre = s0 + 0.5 / std::abs(ud[axis]);
    const Layer rho{rho_.side[static_cast<size_t>(face)], n[ta], n[2], periodic_[ta], false};
    double t = h * rho.segment_integral(e[ta], e[2], ud[ta], u.z, std::min(s_centre, s1) - s0);
    if (s_centre < s1)
        t += Layer{tau.side[static_cast<size_t>(face)], n[ta], n[2], periodic_[ta], false}.bilinear_centres(
            q[ta] + s_centre * ud[ta], s_centre * u.z);
    return t;
}

double GroundShading::radiance_bound(int b) const {
    if (albedo_.empty()) return 0.0;
    double E = 0.0;
    for (const auto& l : in_.light.lights) E += std::abs(band_value(l.E0, b)) * std::max(0.0, -l.w.z);
    return albedo_[static_cast<size_t>(b)] / std::numbers::pi * E;
}

bool GroundShading::shade(const Vec3& o, const Vec3& d, double* L) const {
    if (!active_ || !(d.z < 0.0)) return false;
    const Grid& grid = in_.medium.grid;
    const double t = (grid.origin.z - o.z) / d.z;
    if (!(t > 0.0)) return false;
    double qx = (o.x + t * d.x - grid.origin.x) / grid.h, qy = (o.y + t * d.y - grid.origin.y) / grid.h;
    const int nx = grid.n[0], ny = grid.n[1];
    // Along a periodic axis the medium, and so its shadow, repeats.
    if (periodic_[0]) qx -= nx * std::floor(qx / nx);
    if (periodic_[1]) qy -= ny * std::floor(qy / ny);
    const int ix = std::clamp(qx < 0 ? -1 : static_cast<int>(std::min(qx, 2.0 * nx)), 0, nx - 1);
    const int iy = std::clamp(qy < 0 ? -1 : static_cast<int>(std::min(qy, 2.0 * ny)), 0, ny - 1);
    if (ix < owned_.lo[0] || ix >= owned_.hi[0] || iy < owned_.lo[1] || iy >= owned_.hi[1]) return false;

    const int nb = static_cast<int>(albedo_.size());
    const auto& lights = in_.light.lights;
    for (int b = 0; b < nb; ++b) L[b] = 0.0;
    for (size_t l = 0; l < lights.size(); ++l) {
        const double cos_in = std::max(0.0, -lights[l].w.z);
        if (cos_in == 0.0) continue;
        const double tau = shadows_ ? ground_tau(l, qx, qy) : 0.0;
        for (int b = 0; b < nb; ++b) {
            const double T = tau > 0.0 ? std::exp(-in_.medium.bands[static_cast<size_t>(b)].sigma_t * tau) : 1.0;
            L[b] += band_value(lights[l].E0, b) * cos_in * T;
        }
    }
    for (int b = 0; b < nb; ++b) L[b] *= albedo_[static_cast<size_t>(b)] / std::numbers::pi;
    return true;
}

}  // namespace nimbus
