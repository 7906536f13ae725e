#include "solvers/light/sun_transmittance.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "src/core/error.h"
#include "solvers/light/exact_chain.h"
#include "src/core/gather.h"
#include "src/core/halo.h"
#include "src/core/progress.h"

namespace nimbus {
namespace {

// The fixed stencil of one direction: segment pieces (cell offset, length) and the bilinear
// taps (cell offset, weight) of the upwind plane. Same for every cell.
struct Stencil {
    struct Piece { Int3 off; double length; };
    struct Tap { Int3 off; double weight; };
    std::vector<Piece> pieces;
    std::array<Tap, 4> taps;
};

// m: the axis whose upwind layer the segment starts from (segment_axis). Normally the dominant
// axis of w (then |offsets| <= 1); with a periodic axis, the dominant one of the non-periodic
// axes, and the upwind point may lie several cells away along the periodic axes (f > 1), which
// periodic wrapping makes available.
Stencil make_stencil(const Vec3& w, double h, int m) {
    Stencil st;
    const double wm = std::abs(w[m]);
    const double t = h / wm;  // segment length from the upwind plane to the centre
    // Position relative to the centre, in cells: x(u) = (u - 1) * w / |w_m| for u in [0, 1];
    // it crosses a cell face where |x_a| = q + 1/2.
    std::vector<double> breaks{0.0, 1.0};
    for (int a = 0; a < 3; ++a) {
        const double f = std::abs(w[a]) / wm;
        for (int q = 0; q + 0.5 < f; ++q) breaks.push_back(1.0 - (q + 0.5) / f);
    }
    std::sort(breaks.begin(), breaks.end());
    for (size_t q = 0; q + 1 < breaks.size(); ++q) {
        const double du = breaks[q + 1] - breaks[q];
        if (du <= 1e-15) continue;
        const double um = 0.5 * (breaks[q] + breaks[q + 1]);
        Int3 off{};
        for (int a = 0; a < 3; ++a) off[a] = static_cast<int>(std::lround((um - 1.0) * w[a] / wm));
        st.pieces.push_back({off, du * t});
    }
    // Upwind plane point p: one cell back along m, f_a = |w_a|/|w_m| cells back along a; the
    // taps are the cells floor(f_a) and floor(f_a) + 1 back, weighted by the fractional part.
    const int a = (m + 1) % 3, b = (m + 2) % 3;
    const double fa = std::abs(w[a]) / wm, fb = std::abs(w[b]) / wm;
    const int ia = static_cast<int>(std::floor(fa)), ib = static_cast<int>(std::floor(fb));
    const double ra = fa - ia, rb = fb - ib;
    const int sa = w[a] < 0 ? -1 : 1, sb = w[b] < 0 ? -1 : 1, sm = w[m] < 0 ? -1 : 1;
    int q = 0;
    for (int da = 0; da < 2; ++da)
        for (int db = 0; db < 2; ++db) {
            Int3 off{};
            off[m] = -sm;
            off[a] = -sa * (ia + da);
            off[b] = -sb * (ib + db);
            st.taps[static_cast<size_t>(q++)] = {off, (da ? ra : 1 - ra) * (db ? rb : 1 - rb)};
        }
    return st;
}

// The axis the segments start from: the one of largest |w_a| among the non-periodic axes. A
// periodic axis has no inflow face to start the sweep from; along the other non-periodic axes
// the offsets then stay within one cell (the ghost layer; z is split over the slab chain).
// Along periodic x/y (never split) they may be several cells, wrapped.
int segment_axis(const Decomposition& d, const Vec3& w) {
    int m = -1;
    for (int a = 0; a < 3; ++a)
        if (!d.periodic(a) && (m < 0 || std::abs(w[a]) > std::abs(w[m]))) m = a;
    return m;
}

// The exact pass on the field's slabs along z: the slab chain (exact_chain.h), one light after
// the other; horizontal lights leave every rank on its own. Fills tau_rho (halos exchanged) and
// returns the report's entry, with the chain's balance: the busiest rank's tracing against the
// mean (waits excluded). A rank traces the pieces of every ray that crosses its slab, so ranks
// nearer the light trace more: up to about twice the mean in a uniform medium on many ranks.
nlohmann::json exact_light_on_chain(const Decomposition& d, const Medium& m, const std::vector<DirectionalLight>& lights,
                                    std::vector<Field<double>>& tau_rho, Progress& progress) {
    RayGrid grid = make_slab_grid(d, m.rho);
    double busy_total = 0.0;  // this rank's tracing on the chain, all lights
    for (size_t l = 0; l < lights.size(); ++l) {
        double busy = 0.0;
        exact_tau_chain(d, grid, m.grid.h, lights[l], tau_rho[l], &busy);
        busy_total += busy;
        exchange_halo(tau_rho[l], d);
        progress.update(static_cast<double>(l + 1));
    }
    double busy[2] = {busy_total, busy_total};
    MPI_Allreduce(MPI_IN_PLACE, &busy[0], 1, MPI_DOUBLE, MPI_MAX, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &busy[1], 1, MPI_DOUBLE, MPI_SUM, d.comm());
    return {{"terms", lights.size()}, {"method", "exact (slab chain)"}, {"replicated_memory_gb", 0.0},
            {"z_cuts", d.cuts(2)}, {"trace_seconds_max", busy[0]}, {"trace_seconds_mean", busy[1] / d.size()}};
}

// Long characteristics: every owned cell traces its own ray. Slabs along z: pipelined down the
// chain, no replication (exact_light_on_chain). Other process grids: every rank traces its own
// cells through a replicated density.
LightTransport exact_light_transport(const Decomposition& d, const Medium& m,
                                     const std::vector<DirectionalLight>& lights, Report& report) {
    LightTransport lt;
    lt.lights = lights;
    for (size_t l = 0; l < lights.size(); ++l) lt.tau_rho.emplace_back(d.local(), 1, 1, 0.0);
    Progress progress("light pass (exact)", static_cast<double>(lights.size()), d.rank() == 0);
    if (d.is_slab_z()) {
        report.values()["light"] = exact_light_on_chain(d, m, lights, lt.tau_rho, progress);
    } else {
        const Int3 n = d.global().hi;
        const std::array<bool, 3> periodic{d.periodic(0), d.periodic(1), d.periodic(2)};
        // The whole domain's density (8 bytes per cell once the gathered copy is released).
        RayGrid grid = [&] {
            const std::vector<double> rho = allgather_global(m.rho, d);
            return make_ray_grid(d.global(), n, periodic, [&](int i, int j, int k) {
                return rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i];
            });
        }();
        std::vector<RaySegment> segments;
        for (size_t l = 0; l < lights.size(); ++l) {
            const Vec3 b = -normalized(lights[l].w);
            Field<double>& tau = lt.tau_rho[l];
            const Box& own = d.local();
            std::vector<double> layer(static_cast<size_t>(own.size(0)) * own.size(1));
            for (int k = own.lo[2]; k < own.hi[2]; ++k) {
                integrate_layer(grid, own, b, k, false, 0.0, segments, layer.data());
                auto value = layer.begin();
                for (int j = own.lo[1]; j < own.hi[1]; ++j)
                    for (int i = own.lo[0]; i < own.hi[0]; ++i) tau(i, j, k) = *value++ * m.grid.h;
            }
            exchange_halo(tau, d);
            progress.update(static_cast<double>(l + 1));
        }
        const double grid_bytes = static_cast<double>(grid.rho.size()) * sizeof(double) +
                                  static_cast<double>(grid.row_lo.size() + grid.row_hi.size()) * sizeof(int);
        report.values()["light"] = {{"terms", lights.size()}, {"method", "exact (replicated)"},
                                    {"replicated_memory_gb", 1e-9 * grid_bytes}};
    }
    progress.finish();
    return lt;
}

}  // namespace

void check_light_method(const Decomposition& d, LightSpec::Method method) {
    if (method == LightSpec::Method::sweep && !d.is_slab_z())
        throw Error(fmt::format("light.method = \"sweep\" sweeps along z and needs slabs along z "
                                "(grid.process_grid = [1, 1, P]); got {}; use light.method = \"exact\"",
                                d.describe()));
}

void check_lights_leave(const Decomposition& d, const std::vector<DirectionalLight>& lights) {
    const Int3 n = d.global().shape();
    for (const auto& light : lights) {
        // Path to the nearest non-periodic face it can leave through (cells), and how often it
        // wraps around the periodic axes on the way.
        double path = std::numeric_limits<double>::infinity();
        for (int a = 0; a < 3; ++a)
            if (!d.periodic(a) && light.w[a] != 0.0) path = std::min(path, n[a] / std::abs(light.w[a]));
        double wraps = 0.0;
        for (int a = 0; a < 3; ++a)
            if (d.periodic(a)) wraps = std::max(wraps, path * std::abs(light.w[a]) / n[a]);
        if (!std::isfinite(path))
            throw Error(fmt::format("light '{}' travels along periodic axes only: it never leaves the domain",
                                    light.name));
        if (wraps > kMaxLightWraps)
            throw Error(fmt::format("light '{}' (direction [{:.3g}, {:.3g}, {:.3g}]) would cross the periodic domain "
                                    "{:.3g} times before it leaves (at most {:g}): make it less parallel to the "
                                    "periodic axes, or set those axes non-periodic",
                                    light.name, light.w.x, light.w.y, light.w.z, wraps, kMaxLightWraps));
        if (d.periodic(2) && light.w.z != 0.0)
            throw Error(fmt::format("light '{}' is not horizontal (direction z = {:.3g}) and grid.periodic z is "
                                    "set: light leaving through the bottom would enter again at the top, which "
                                    "the light pass does not model; set grid.periodic = [x, y, false] (periodic z "
                                    "suits horizontal light and volume sources)",
                                    light.name, light.w.z));
    }
}

LightTransport compute_light_transport(const Decomposition& d, const Medium& m,
                                       const std::vector<DirectionalLight>& lights, Report& report,
                                       const sweep::SweepOptions& opt, LightSpec::Method method) {
    ScopedTimer timer(report, "light");
    check_light_method(d, method);
    check_lights_leave(d, lights);
    if (method == LightSpec::Method::exact) return exact_light_transport(d, m, lights, report);
    LightTransport lt;
    lt.lights = lights;
    const Int3 n = d.global().hi;
    double wait = 0;
    int passes = 1;  // the most sweeps any light took
    Progress progress("light pass", static_cast<double>(lights.size()), d.rank() == 0);
    for (const auto& light : lights) {
        const bool periodic_xy = d.periodic(0) || d.periodic(1);
        const int seg_axis = segment_axis(d, light.w);  // z is never periodic for a non-horizontal light here
        if (periodic_xy && std::abs(light.w[seg_axis]) < 1e-3)
            throw Error(fmt::format("light '{}' runs along the periodic axes (direction [{:.3g}, {:.3g}, {:.3g}]): "
                                    "the sweep needs it to cross a non-periodic axis; use light.method = \"exact\"",
                                    light.name, light.w.x, light.w.y, light.w.z));
        const Stencil st = make_stencil(light.w, m.grid.h, seg_axis);
        Field<double> tau(d.local(), 1, 1, 0.0);  // ghosts outside the domain stay 0: vacuum
        // Periodic x/y: wrap indices into the domain (x/y are never split: slabs along z).
        auto wrap = [&](int v, int axis) {
            return d.periodic(axis) ? (v % n[axis] + n[axis]) % n[axis] : v;
        };
        const auto& rho = m.rho;
        sweep::SweepOptions sopt = opt;
        if (periodic_xy) sopt.tile_rows = n[1];  // a whole upwind layer is done before the next
        // Without periodic wrapping every piece and tap is a fixed offset from the cell's index
        // (rho and tau share the owned box and ghost width, hence the layout): flatten them.
        constexpr int kMax = 8;
        std::ptrdiff_t piece_off[kMax], tap_off[4];
        double piece_len[kMax], tap_w[4];
        const int npieces = static_cast<int>(st.pieces.size());
        for (int q = 0; q < npieces && q < kMax; ++q) {
            const auto& p = st.pieces[static_cast<size_t>(q)];
            piece_off[q] = p.off[0] * tau.stride(0) + p.off[1] * tau.stride(1) + p.off[2] * tau.stride(2);
            piece_len[q] = p.length;
        }
        for (int q = 0; q < 4; ++q) {
            const auto& tp = st.taps[static_cast<size_t>(q)];
            tap_off[q] = tp.off[0] * tau.stride(0) + tp.off[1] * tau.stride(1) + tp.off[2] * tau.stride(2);
            tap_w[q] = tp.weight;
        }
        const double* rho_p = m.rho.data();
        double* tau_p = tau.data();
        const bool flat = !periodic_xy && npieces <= kMax && rho.allocated() == tau.allocated();
        auto kernel = [&](int i, int j, int k) {
            if (flat) {
                const std::ptrdiff_t c = tau.index(i, j, k);
                double t = tap_w[0] * tau_p[c + tap_off[0]] + tap_w[1] * tau_p[c + tap_off[1]] +
                           tap_w[2] * tau_p[c + tap_off[2]] + tap_w[3] * tau_p[c + tap_off[3]];
                for (int q = 0; q < npieces; ++q) t += piece_len[q] * rho_p[c + piece_off[q]];
                tau_p[c] = t;
                return;
            }
            double t = 0.0;
            for (const auto& p : st.pieces)
                t += p.length * rho(wrap(i + p.off[0], 0), wrap(j + p.off[1], 1), k + p.off[2]);
            for (const auto& tap : st.taps)
                if (tap.weight != 0.0)
                    t += tap.weight * tau(wrap(i + tap.off[0], 0), wrap(j + tap.off[1], 1), k + tap.off[2]);
            tau(i, j, k) = t;
        };
        // The engine visits k, then rows j, then i. Segments from the x layer over periodic y
        // read plane i - 1 at wrapped rows that this order may reach only later in the pass:
        // sweep again until nothing changes (each pass carries the light across one more wrap;
        // the taps are strictly upwind in x, so at most n_x + 1 passes; equal bits mean final).
        const bool wrapped_rows_later = seg_axis == 0 && d.periodic(1);
        std::vector<double> before;
        for (int pass = 1;; ++pass) {
            if (wrapped_rows_later) before = tau.owned_values();
            const auto stats = sweep::run(d, tau, sweep::Octant::of(light.w), sopt, kernel);
            wait += stats.wait_seconds;
            if (!wrapped_rows_later) break;
            int changed = tau.owned_values() != before ? 1 : 0;
            MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_LOR, d.comm());
            passes = std::max(passes, pass);
            if (!changed) break;
            if (pass > n[0] + 1)
                throw Error(fmt::format("light pass: light '{}' still changes after {} sweeps over periodic y",
                                        light.name, pass));
        }
        exchange_halo(tau, d);
        lt.tau_rho.push_back(std::move(tau));
        progress.update(static_cast<double>(lt.tau_rho.size()));
    }
    progress.finish();
    report.values()["light"] = {{"terms", lights.size()}, {"method", "sweep"},
                                {"pipeline_wait_seconds_rank0", wait}, {"sweeps_per_light_max", passes}};
    return lt;
}

double exact_tau_rho(const std::vector<double>& rho, const Int3& n, double h, const Vec3& w, int i,
                     int j, int k, std::array<bool, 3> periodic) {
    // March from the cell centre along -w through the cell grid (units of cells).
    const Vec3 dir = -w / norm(w);
    double pos[3] = {i + 0.5, j + 0.5, k + 0.5};
    int cell[3] = {i, j, k}, step[3];
    double tmax[3], tdelta[3];
    for (int a = 0; a < 3; ++a) {
        const double da = dir[a];
        step[a] = da > 0 ? 1 : -1;
        tdelta[a] = da != 0 ? std::abs(1.0 / da) : std::numeric_limits<double>::infinity();
        const double next = da > 0 ? std::floor(pos[a]) + 1.0 : std::floor(pos[a]);
        tmax[a] = da != 0 ? (next - pos[a]) / da : std::numeric_limits<double>::infinity();
    }
    double t = 0.0, tau = 0.0;
    while (true) {
        const int a = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
        const double r = rho[(static_cast<size_t>(cell[2]) * n[1] + cell[1]) * n[0] + cell[0]];
        tau += r * (tmax[a] - t) * h;
        t = tmax[a];
        cell[a] += step[a];
        tmax[a] += tdelta[a];
        if (cell[a] < 0 || cell[a] >= n[a]) {
            if (!periodic[a]) break;
            cell[a] = (cell[a] + n[a]) % n[a];
        }
    }
    return tau;
}

}  // namespace nimbus
