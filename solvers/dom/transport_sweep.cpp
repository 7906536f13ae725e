#include "solvers/dom/transport_sweep.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "solvers/dom/cell_kernel.h"
#include "src/core/error.h"

namespace nimbus::dom {
namespace {

constexpr int kMaxPeriodicPasses = 10000;

// Offset of cell (i, j, k) in a ghost-free field on box b, in cells.
inline std::ptrdiff_t cell_offset(const Box& b, int i, int j, int k) {
    return (static_cast<std::ptrdiff_t>(k - b.lo[2]) * b.size(1) + (j - b.lo[1])) * b.size(0) + (i - b.lo[0]);
}

}  // namespace

TransportSweeper::TransportSweeper(const Decomposition& d, const AngularSet& ang, double h,
                                   const sweep::SweepOptions& opt, double periodic_tolerance)
    : d_(d), ang_(ang), h_(h), opt_(opt), periodic_tol_(periodic_tolerance) {
    for (int a = 0; a < 2; ++a)
        if (d.periodic(a) && d.dims()[a] != 1)
            throw Error(fmt::format("dom: periodic axis {} must not be split over ranks ({})", "xy"[a], d.describe()));
    if (d.periodic(2)) throw Error("dom: periodic z is not supported");
    if (d.periodic(0) || d.periodic(1)) opt_.tile_rows = d.local().size(1);  // whole layers
    for (int o = 0; o < 8; ++o) {
        const auto& oc = ang.octants[static_cast<size_t>(o)];
        const size_t nd = static_cast<size_t>(oc.size());
        auto& c = coef_[static_cast<size_t>(o)];
        for (auto& v : c) v.assign(nd, 0.0);
        for (size_t n = 0; n < nd; ++n) {
            for (size_t a = 0; a < 3; ++a) c[a][n] = oc.abs_mu[a][n] / h;
            c[3][n] = c[0][n] + c[1][n] + c[2][n];
        }
        if (nd > 0 && psi_.find(oc.size()) == psi_.end()) psi_.emplace(oc.size(), Field<double>(d.local(), 1, oc.size(), 0.0));
    }
}

void TransportSweeper::set_upwind_ghosts(Field<double>& psi, int o) {
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const Box& own = d_.local();
    for (int a = 0; a < 3; ++a) {
        const int s = oc.octant.s[a];
        const bool at_boundary = s > 0 ? d_.at_low_boundary(a) : d_.at_high_boundary(a);
        // Interior faces are filled by the engine from upstream; periodic ones per layer.
        if (!at_boundary || d_.periodic(a)) continue;
        Box p = own;
        p.lo[a] = s > 0 ? own.lo[a] - 1 : own.hi[a];
        p.hi[a] = p.lo[a] + 1;
        for_each_cell(p, [&](int i, int j, int k) {
            double* v = &psi(i, j, k);
            for (int c = 0; c < psi.ncomp(); ++c) v[c] = 0.0;  // vacuum
        });
    }
}

void TransportSweeper::reduce_octant(const Field<double>& psi, int o, SweepOutput& out) {
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const int nd = oc.size(), nmom = ang_.nmom;
    const Box& own = d_.local();
    const Box& g = d_.global();
    const double area = h_ * h_;
    for_octant_size(nd, [&](auto size) {
        constexpr int ND = decltype(size)::value;
        for_each_cell(own, [&](int i, int j, int k) {
            const double* p = &psi(i, j, k);
            const std::ptrdiff_t c = cell_offset(own, i, j, k);
            if constexpr (ND > 0)
                accumulate_moments_n<ND>(nmom, oc.wY.data(), p, out.phi.data() + c * nmom);
            else
                accumulate_moments(nd, nmom, oc.wY.data(), p, out.phi.data() + c * nmom);
            double f = 0.0, F[3] = {0.0, 0.0, 0.0};
            for (int n = 0; n < nd; ++n) {
                const double wp = oc.weight[static_cast<size_t>(n)] * p[n];
                const Vec3& w = oc.dir[static_cast<size_t>(n)];
                f += wp;
                F[0] += wp * w.x;
                F[1] += wp * w.y;
                F[2] += wp * w.z;
            }
            out.fluence.data()[c] += f;
            for (int a = 0; a < 3; ++a) out.flux.data()[c * 3 + a] += F[a];
            const int idx[3] = {i, j, k};
            for (int a = 0; a < 3; ++a) {
                if (d_.periodic(a)) continue;
                const int s = oc.octant.s[a];
                const bool edge = s > 0 ? idx[a] == g.hi[a] - 1 : idx[a] == g.lo[a];
                if (edge) out.leakage[static_cast<size_t>(2 * a + (s > 0 ? 1 : 0))] += area * std::abs(F[a]);
            }
        });
    });
}

void TransportSweeper::sweep(const SweepSource& src, SweepOutput& out) {
    const Box& own = d_.local();
    const int nmom = ang_.nmom;
    if (out.phi.owned() != own || out.phi.ncomp() != nmom) {
        out.phi = Field<double>(own, 0, nmom, 0.0);
        out.fluence = Field<double>(own, 0, 1, 0.0);
        out.flux = Field<double>(own, 0, 3, 0.0);
    } else {
        out.phi.fill(0.0);
        out.fluence.fill(0.0);
        out.flux.fill(0.0);
    }
    out.leakage.fill(0.0);
    const double* kap = src.kappa->data();
    const double* mom = src.moments->data();
    const double* amp = src.nl > 0 ? src.amp->data() : nullptr;
    const int nl = src.nl;
    for (int o = 0; o < 8; ++o) {
        const auto& oc = ang_.octants[static_cast<size_t>(o)];
        const int nd = oc.size();
        if (nd == 0) continue;
        Field<double>& psi = psi_.at(nd);
        const auto& c = coef_[static_cast<size_t>(o)];
        const double *cx = c[0].data(), *cy = c[1].data(), *cz = c[2].data(), *cs = c[3].data();
        const double* Y = oc.Y.data();
        const double* P = src.light_phase[static_cast<size_t>(o)].data();
        // The octant's source for every cell first (Kripke's LPlusTimes), so that repeated
        // periodic passes only redo the cheap transport kernel.
        std::vector<double>& Sq = source_;
        Sq.resize(static_cast<size_t>(own.cells() * nd));
        const double t_src = MPI_Wtime();
        for_octant_size(nd, [&](auto size) {
            constexpr int ND = decltype(size)::value;
            const std::ptrdiff_t ncell = own.cells();
            double* S = Sq.data();
            for (std::ptrdiff_t cell = 0; cell < ncell; ++cell) {
                const double* A = amp ? amp + cell * nl : nullptr;
                if constexpr (ND > 0)
                    cell_source_n<ND>(nl, nmom, A, P, Y, mom + cell * nmom, S + cell * ND);
                else
                    cell_source(nd, nl, nmom, A, P, Y, mom + cell * nmom, S + cell * nd);
            }
        });
        timing_.moment_seconds += MPI_Wtime() - t_src;
        const double* Sp = Sq.data();
        double* pp = psi.data();
        const std::ptrdiff_t ox = oc.octant.s[0] * psi.stride(0), oy = oc.octant.s[1] * psi.stride(1),
                             oz = oc.octant.s[2] * psi.stride(2);
        auto cell_kernel = [&](int i, int j, int k) {
            const std::ptrdiff_t cell = cell_offset(own, i, j, k);
            double* p = pp + psi.index(i, j, k);
            step_cell(nd, kap[cell], Sp + cell * nd, cx, cy, cz, cs, p - ox, p - oy, p - oz, p);
        };
        // Periodic x/y: the engine sweeps whole z layers (one tile); after the last cell of a
        // layer, the layer's periodic ghosts are set to its downwind edges and the layer is
        // recomputed until they agree (local: no communication).
        const bool periodic = d_.periodic(0) || d_.periodic(1);
        const sweep::AxisRange rx = sweep::upwind_range(own, 0, oc.octant), ry = sweep::upwind_range(own, 1, oc.octant);
        const int last_i = rx.end - rx.step, last_j = ry.end - ry.step;
        auto periodic_layer = [&](int k) {
            for (int pass = 0;; ++pass) {
                double change = 0.0, scale = 0.0;
                for (int a = 0; a < 2; ++a) {
                    if (!d_.periodic(a)) continue;
                    const int s = oc.octant.s[a];
                    const int ghost = s > 0 ? own.lo[a] - 1 : own.hi[a], edge = s > 0 ? own.hi[a] - 1 : own.lo[a];
                    const int b = 1 - a;
                    for (int t = own.lo[b]; t < own.hi[b]; ++t) {
                        double* g = a == 0 ? &psi(ghost, t, k) : &psi(t, ghost, k);
                        const double* e = a == 0 ? &psi(edge, t, k) : &psi(t, edge, k);
                        for (int n = 0; n < nd; ++n) {
                            change = std::max(change, std::abs(e[n] - g[n]));
                            scale = std::max(scale, std::abs(e[n]));
                            g[n] = e[n];
                        }
                    }
                }
                if (change <= periodic_tol_ * scale) return;
                if (pass >= kMaxPeriodicPasses) {
                    periodic_failure_ = std::max(periodic_failure_, change / scale);
                    return;
                }
                ++timing_.periodic_passes;
                timing_.cell_directions += static_cast<std::int64_t>(own.size(0)) * own.size(1) * nd;
                for (int j = ry.first; j != ry.end; j += ry.step)
                    for (int i = rx.first; i != rx.end; i += rx.step) cell_kernel(i, j, k);
            }
        };
        auto kernel = [&](int i, int j, int k) {
            cell_kernel(i, j, k);
            if (periodic && i == last_i && j == last_j) periodic_layer(k);
        };
        set_upwind_ghosts(psi, o);
        const double t0 = MPI_Wtime();
        const auto stats = sweep::run(d_, psi, oc.octant, opt_, kernel);
        timing_.sweep_seconds += MPI_Wtime() - t0;
        timing_.wait_seconds += stats.wait_seconds;
        timing_.cell_directions += own.cells() * nd;
        const double t1 = MPI_Wtime();
        reduce_octant(psi, o, out);
        timing_.moment_seconds += MPI_Wtime() - t1;
    }
    MPI_Allreduce(MPI_IN_PLACE, out.leakage.data(), 6, MPI_DOUBLE, MPI_SUM, d_.comm());
    const double failure = periodic_failure_;
    periodic_failure_ = 0.0;
    check_collective(d_.comm(), failure == 0.0,
                     fmt::format("dom: periodic boundary planes did not converge in {} passes (relative change {:.3e})",
                                 kMaxPeriodicPasses, failure));
}

}  // namespace nimbus::dom
