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
OuterLayers gather_outer_layers(const Field<double>& f, const Box& owned, const Int3& n, bool with_top,
                                MPI_Comm comm) {
    OuterLayers out;
    auto horizontal = [&](std::vector<double>& layer, int k) {
        layer.assign(static_cast<size_t>(n[0]) * static_cast<size_t>(n[1]), 0.0);
        if (k < owned.lo[2] || k >= owned.hi[2]) return;
        for (int j = owned.lo[1]; j < owned.hi[1]; ++j)
            for (int i = owned.lo[0]; i < owned.hi[0]; ++i)
                layer[static_cast<size_t>(j) * static_cast<size_t>(n[0]) + static_cast<size_t>(i)] = f(i, j, k);
    };
    horizontal(out.bottom, 0);
    if (with_top) horizontal(out.top, n[2] - 1);
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
    all.insert(all.end(), out.top.begin(), out.top.end());
    for (const auto& side : out.side) all.insert(all.end(), side.begin(), side.end());
    MPI_Allreduce(MPI_IN_PLACE, all.data(), static_cast<int>(all.size()), MPI_DOUBLE, MPI_SUM, comm);
    auto at = all.begin();
    for (std::vector<double>* part : {&out.bottom, &out.top, &out.side[0], &out.side[1], &out.side[2], &out.side[3]}) {
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
};

}  // namespace

double GroundShading::outer_layer_values(const Int3& n) {
    return 2.0 * static_cast<double>(n[0]) * n[1] + 2.0 * (static_cast<double>(n[0]) + n[1]) * n[2];
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
    // The shell walk reads the top layer's density too; lookups of tau_rho never reach the top
    // (the ray goes up, so it enters the core from below or from a side).
    rho_ = gather_outer_layers(in.medium.rho, owned_, n, true, d.comm());
    for (const auto& tau : in.light.tau_rho) {
        OuterLayers layers = gather_outer_layers(tau, owned_, n, false, d.comm());
        if (active_) tau_.push_back(std::move(layers));  // only the ranks with a part of the bottom shade
    }
    if (!active_) rho_ = OuterLayers{};
}

double GroundShading::outer_rho(int i, int j, int k) const {
    const Int3& n = in_.medium.grid.n;
    i = Layer::wrap(i, n[0], periodic_[0]), j = Layer::wrap(j, n[1], periodic_[1]), k = std::clamp(k, 0, n[2] - 1);
    auto at = [](const std::vector<double>& v, int nt, int t, int kk) {
        return v[static_cast<size_t>(kk) * static_cast<size_t>(nt) + static_cast<size_t>(t)];
    };
    if (k == 0) return at(rho_.bottom, n[0], i, j);
    if (k == n[2] - 1) return at(rho_.top, n[0], i, j);
    if (!periodic_[0] && (i == 0 || i == n[0] - 1)) return at(rho_.side[i == 0 ? 0 : 1], n[1], j, k);
    if (!periodic_[1] && (j == 0 || j == n[1] - 1)) return at(rho_.side[j == 0 ? 2 : 3], n[0], i, k);
    return 0.0;  // not an outer cell: reached only by round-off at the core's surface
}

double GroundShading::shell_integral(double qx, double qy, const Vec3& u, double sa, double sb) const {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const double q[3] = {qx, qy, 0.0}, ud[3] = {u.x, u.y, u.z};
    auto to_next_line = [&](int a, double s) {
        const double x = q[a] + s * ud[a];
        return ud[a] > 0 ? (std::floor(x) + 1 - x) / ud[a] : ud[a] < 0 ? (x - (std::ceil(x) - 1)) / -ud[a] : kInf;
    };
    const double min_step = 1e-12 * std::max(1.0, sb - sa);  // no stall on a line hit by round-off
    double sum = 0, s = sa;
    while (s < sb) {
        const double ds = std::min(sb - s, std::max(min_step, std::min({to_next_line(0, s), to_next_line(1, s),
                                                                         to_next_line(2, s)})));
        const double sm = s + 0.5 * ds;  // the piece's midpoint names its cell
        int c[3];
        for (int a = 0; a < 3; ++a) c[a] = static_cast<int>(std::floor(q[a] + sm * ud[a]));
        sum += ds * outer_rho(c[0], c[1], c[2]);
        s += ds;
    }
    return sum;
}

double GroundShading::ground_tau(size_t l, double qx, double qy) const {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const Int3& n = in_.medium.grid.n;
    const Vec3 u = -in_.light.lights[l].w;  // toward the light, u.z > 0
    const double q[3] = {qx, qy, 0.0}, ud[3] = {u.x, u.y, u.z};
    // The ray q + s u (s >= 0, cells) against the box [lo, n_a - lo] per axis (unbounded along
    // periodic x/y): the domain (lo = 0) and the core, the box of the cell centres (lo = 1/2).
    // Returns [enter, leave] and the axis entered through (-1: none, the ray starts inside).
    struct Span {
        double enter = -kInf, leave = kInf;
        int axis = -1;
    };
    auto span = [&](double lo) {
        Span r;
        for (int a = 0; a < 3; ++a) {
            if (a < 2 && periodic_[a]) continue;
            const double b0 = lo, b1 = n[a] - lo;
            if (ud[a] == 0.0) {
                if (q[a] < b0 || q[a] > b1) r.leave = -kInf;  // beside the box, parallel to it
                continue;
            }
            const double s0 = (b0 - q[a]) / ud[a], s1 = (b1 - q[a]) / ud[a];
            if (std::min(s0, s1) > r.enter) r.enter = std::min(s0, s1), r.axis = a;
            r.leave = std::min(r.leave, std::max(s0, s1));
        }
        return r;
    };
    const Span domain = span(0.0), core = span(0.5);
    const double s0 = std::max(domain.enter, 0.0);
    if (!(s0 < domain.leave)) return 0.0;  // misses the domain
    // The core has an inside (every n_a >= 2) and the ray enters it: through the outer shell
    // exactly, then tau_rho on the core's face where it enters, bilinear between the centres of
    // that outer layer (an interpolation: the point lies within the face's centres).
    const bool hits_core = core.enter < core.leave && core.enter >= s0;
    const double h = in_.medium.grid.h;
    double tau = h * shell_integral(qx, qy, u, s0, hits_core ? core.enter : domain.leave);
    if (!hits_core) return tau;
    const double p[3] = {qx + core.enter * u.x, qy + core.enter * u.y, core.enter * u.z};
    const OuterLayers& t = tau_[l];
    if (core.axis == 2)
        return tau + Layer{t.bottom, n[0], n[1], periodic_[0], periodic_[1]}.bilinear_centres(p[0], p[1]);
    const int axis = core.axis, ta = 1 - axis;
    const int face = 2 * axis + (ud[axis] > 0.0 ? 0 : 1);  // entered from its low side: the low face's layer
    return tau + Layer{t.side[static_cast<size_t>(face)], n[ta], n[2], periodic_[ta], false}.bilinear_centres(p[ta], p[2]);
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
