#include "solvers/dom/transport_sweep.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "solvers/dom/cell_kernel.h"
#include "solvers/dom/moment_kernels.h"
#include "src/core/anderson.h"
#include "src/core/error.h"

namespace nimbus::dom {
namespace {

constexpr int kMaxPeriodicPasses = 10000;
// Anderson acceleration of diamond's periodic layer iteration (periodic_layer): columns kept.
constexpr int kPeriodicAndersonDepth = 5;
constexpr const char* kFaceNames[6] = {"x-", "x+", "y-", "y+", "z-", "z+"};

// Smallest value of any component over the cells of b.
double min_over(const Field<double>& psi, const Box& b) {
    double m = std::numeric_limits<double>::infinity();
    for_each_cell(b, [&](int i, int j, int k) {
        const double* v = &psi(i, j, k);
        for (int c = 0; c < psi.ncomp(); ++c) m = std::min(m, v[c]);
    });
    return m;
}

// Offset of cell (i, j, k) in a ghost-free field on box b, in cells.
inline std::ptrdiff_t cell_offset(const Box& b, int i, int j, int k) {
    return (static_cast<std::ptrdiff_t>(k - b.lo[2]) * b.size(1) + (j - b.lo[1])) * b.size(0) + (i - b.lo[0]);
}

// Octant groups swept at once (DomOptions::octant_overlap, sweep::run_octants): 1: each octant
// alone; 2: the +z/-z pairs with equal x/y signs {xy, xy + 4}; 8: all at once. Groups run in
// the order of their octants' x/y bits, so a reflective LOW x/y face still sees its mirrored
// octant finished earlier in the same sweep (transport_sweep.h). A reflective z- face needs
// octant o before o + 4, so it limits the overlap to 1; a reflective x- or y- face limits 8 to 2.
// Periodic x/y planes start from the octant's own previous sweep (periodic_planes_), whichever
// field it runs in, so any overlap gives the same result.
std::vector<std::vector<int>> octant_groups(int overlap, const std::array<bool, 6>& reflective) {
    if (overlap == 8 && (reflective[0] || reflective[2] || reflective[4])) overlap = 2;
    if (overlap == 2 && reflective[4]) overlap = 1;
    std::vector<std::vector<int>> groups;
    if (overlap == 8) return {{0, 1, 2, 3, 4, 5, 6, 7}};
    for (int xy = 0; xy < 4; ++xy) {
        if (overlap == 2) groups.push_back({xy, xy + 4});
    }
    if (overlap == 2) return groups;
    for (int o = 0; o < 8; ++o) groups.push_back({o});
    return groups;
}

// One octant in flight: its psi field and source, and the loop constants of its kernel.
struct OctantSlot {
    int o = 0, nd = 0;
    sweep::Octant octant;
    Field<double>* psi = nullptr;
    SourceBuffer* source = nullptr;
    const double *cx = nullptr, *cy = nullptr, *cz = nullptr, *cs = nullptr;
    std::ptrdiff_t ox = 0, oy = 0, oz = 0;  // upwind neighbour offsets in psi
    int fx = 0, fy = 0, fz = 0;             // face blocks (diamond)
    sweep::AxisRange rx{0, 0, 1}, ry{0, 0, 1};
    int last_i = 0, last_j = 0;             // the last cell of a layer (periodic iteration)
    std::vector<double> ghosts, edges;      // a layer's periodic ghost and edge values (periodic_layer)
    std::int64_t fixups = 0;
};

// Each octant's source (Kripke's LPlusTimes, moment_kernels.h) on the source rows' spans, in
// chunks of cells with all octants of the group per chunk, so the chunk's source moments are
// read from memory once; zero elsewhere (written only when the buffer's last rows differ:
// SourceBuffer). Cells are written in increasing order: the vector stores of a chunk's last cell
// may run 3 values past it (zeros, moment_kernels.h) into the cells after it, which are either
// written afterwards or a gap that holds zeros anyway (+3 at the end of the array).
void group_sources(const Box& own, const SweepSource& src, const SourceRows& rows, const AngularSet& ang,
                   std::vector<OctantSlot>& slots) {
    const int nl = src.nl, nmom = ang.nmom;
    const double* amp = nl > 0 ? src.amp->data() : nullptr;
    const double* mom = src.moments.data();  // packed on rows
    std::vector<OctantSourceOp> ops;
    std::vector<SourceBuffer*> stale;  // buffers whose cells outside the spans may be nonzero
    for (OctantSlot& sl : slots) {
        SourceBuffer& b = *sl.source;
        const size_t size = static_cast<size_t>(own.cells() * sl.nd + 3);
        const bool gaps_zero = b.zero_rows && b.nd == sl.nd && b.values.size() == size && *b.zero_rows == rows;
        b.values.resize(size);
        b.nd = sl.nd;
        if (!gaps_zero) stale.push_back(&b);
        ops.push_back(make_octant_source_op(sl.nd, nl, nmom, src.light_phase[static_cast<size_t>(sl.o)].data(),
                                            ang.octants[static_cast<size_t>(sl.o)].Y.data()));
    }
    // Zero source on cells [c0, c1) of the stale buffers.
    auto zero = [&](std::ptrdiff_t c0, std::ptrdiff_t c1) {
        if (c1 <= c0) return;
        for (SourceBuffer* b : stale) std::fill(b->values.data() + c0 * b->nd, b->values.data() + c1 * b->nd, 0.0);
    };
    constexpr std::ptrdiff_t kChunk = 128;  // cells (25 moments: 25 KB of source moments)
    // Cells [c0, c1) of a span, whose source moments start at packed place q.
    auto compute = [&](std::ptrdiff_t c0, std::ptrdiff_t c1, std::ptrdiff_t q) {
        for (; c0 < c1; c0 += kChunk, q += kChunk) {
            const std::ptrdiff_t n = std::min(kChunk, c1 - c0);
            for (size_t o = 0; o < slots.size(); ++o)
                apply_source(ops[o], n, amp ? amp + c0 * nl : nullptr, mom + q * nmom,
                             slots[o].source->values.data() + c0 * slots[o].nd);
        }
    };
    std::ptrdiff_t q = 0;
    for (int k = own.lo[2]; k < own.hi[2]; ++k)
        for (int j = own.lo[1]; j < own.hi[1]; ++j) {
            const std::ptrdiff_t row = cell_offset(own, own.lo[0], j, k);
            const int lo = rows.lo(j, k) - own.lo[0], hi = rows.hi(j, k) - own.lo[0];
            zero(row, row + lo);
            compute(row + lo, row + hi, q);
            zero(row + hi, row + own.size(0));
            q += hi - lo;
        }
    for (SourceBuffer* b : stale) b->zero_rows = rows;
}

// Moments, fluence and flux of the octants of a group (Kripke's LTimes, moment_kernels.h), one
// x row at a time with all octants of the group per row, so the row's moments are read and
// written once per group. first: the sweep's first group, which zeroes each row just before it
// accumulates into it (in cache; a separate fill of the outputs was a 160-byte-per-cell pass
// over memory every sweep, 9% of the DOM phase on the default cloud).
// phi is packed on the source rows (SweepOutput); outside their spans only the fluence and flux
// are reduced (a moment operator with no moments). Only the cells of act (own's part of the
// sweep's region, which holds the spans) were swept: the outputs are 0 elsewhere.
void group_moments(const Box& own, const Box& act, const AngularSet& ang, const std::vector<OctantSlot>& slots,
                   const SourceRows& rows, SweepOutput& out, bool first) {
    const int nmom = ang.nmom;
    std::vector<OctantMomentOp> ops, fluence_ops;
    for (const OctantSlot& sl : slots) {
        const auto& oc = ang.octants[static_cast<size_t>(sl.o)];
        ops.push_back(make_octant_moment_op(sl.nd, nmom, oc.wY.data(), oc.weight.data(), oc.dir.data()));
        fluence_ops.push_back(make_octant_moment_op(sl.nd, 0, nullptr, oc.weight.data(), oc.dir.data()));
    }
    const int nx = own.size(0);
    double* phi = out.phi.data();
    std::ptrdiff_t q = 0;  // packed place of the row's first span cell
    for (int k = own.lo[2]; k < own.hi[2]; ++k)
        for (int j = own.lo[1]; j < own.hi[1]; ++j) {
            const std::ptrdiff_t c = cell_offset(own, own.lo[0], j, k);
            const int lo = rows.lo(j, k) - own.lo[0], hi = rows.hi(j, k) - own.lo[0];
            if (first) {
                std::fill_n(phi + q * nmom, (hi - lo) * nmom, 0.0);
                std::fill_n(out.fluence.data() + c, nx, 0.0);
                std::fill_n(out.flux.data() + 3 * c, 3 * nx, 0.0);
            }
            // The row's swept cells [a0, a1) (none outside act), which hold its span [lo, hi) (a
            // row without one has lo = hi = own.lo[0]: moved to a0, or the cells of own before
            // act, which this sweep did not compute, would be reduced).
            const bool swept = j >= act.lo[1] && j < act.hi[1] && k >= act.lo[2] && k < act.hi[2];
            const int a0 = swept ? act.lo[0] - own.lo[0] : 0, a1 = swept ? act.hi[0] - own.lo[0] : 0;
            const int lo_s = hi > lo ? lo : a0, hi_s = hi > lo ? hi : a0;
            for (size_t o = 0; o < slots.size() && a1 > a0; ++o) {
                const Field<double>& psi = *slots[o].psi;
                const double* p = &psi(own.lo[0], j, k);
                const std::ptrdiff_t ps = psi.stride(0);
                // cells [a, b) of the row with operator op; their moments (if op has any) at phi_a
                auto reduce = [&](const OctantMomentOp& op, int a, int b, double* phi_a) {
                    if (b > a)
                        apply_moments(op, b - a, p + a * ps, ps, phi_a, out.fluence.data() + c + a,
                                      out.flux.data() + 3 * (c + a));
                };
                reduce(fluence_ops[o], a0, lo_s, phi);
                reduce(ops[o], lo_s, hi_s, phi + q * nmom);
                reduce(fluence_ops[o], hi_s, a1, phi);
            }
            q += hi - lo;
        }
}

// The plane of ghost cells through which an octant moving with sign s along axis a enters the
// box own (a domain face's boundary values, or a periodic axis's wrapped ones).
Box upwind_ghost_plane(const Box& own, int a, int s) {
    Box p = own;
    p.lo[a] = s > 0 ? own.lo[a] - 1 : own.hi[a];
    p.hi[a] = p.lo[a] + 1;
    return p;
}

}  // namespace

SourceRows::SourceRows(const Box& own, std::initializer_list<const Field<double>*> fields) : own_(own) {
    const size_t nrow = static_cast<size_t>(own.size(1)) * static_cast<size_t>(own.size(2));
    lo_.assign(nrow, own.hi[0]);
    hi_.assign(nrow, own.lo[0]);
    for (const Field<double>* f : fields) {
        nimbus::for_each_cell(own, [&](int i, int j, int k) {
            const double* v = &(*f)(i, j, k);
            bool nonzero = false;
            for (int c = 0; c < f->ncomp(); ++c) nonzero = nonzero || v[c] != 0.0;
            if (!nonzero) return;
            const size_t r = row(j, k);
            lo_[r] = std::min(lo_[r], i);
            hi_[r] = std::max(hi_[r], i + 1);
        });
    }
    for (size_t r = 0; r < nrow; ++r)
        if (hi_[r] <= lo_[r]) lo_[r] = hi_[r] = own.lo[0];
}

SourceRows::SourceRows(const Box& own)
    : own_(own),
      lo_(static_cast<size_t>(own.size(1)) * static_cast<size_t>(own.size(2)), own.lo[0]),
      hi_(lo_.size(), own.hi[0]) {}

size_t SourceRows::cells() const {
    size_t n = 0;
    for (size_t r = 0; r < lo_.size(); ++r) n += static_cast<size_t>(hi_[r] - lo_[r]);
    return n;
}

double SourceRows::fraction() const {
    return own_.cells() > 0 ? static_cast<double>(cells()) / static_cast<double>(own_.cells()) : 0.0;
}

void check_sweep_decomposition(const Decomposition& d) {
    for (int a = 0; a < 2; ++a)
        if (d.periodic(a) && d.dims()[a] != 1)
            throw Error(fmt::format("model dom: grid.periodic axis {} must not be split over ranks (grid.process_grid; "
                                    "got {})", "xy"[a], d.describe()));
    if (d.periodic(2))
        throw Error("model dom: grid.periodic z is not supported (the sweeps pipeline along z); use periodic x/y only");
}

TransportSweeper::TransportSweeper(const Decomposition& d, const AngularSet& ang, double h,
                                   const sweep::SweepOptions& opt, double periodic_tolerance,
                                   SpatialScheme scheme, const SweepBoundary& boundary, bool fixup)
    : d_(d), ang_(ang), h_(h), opt_(opt), periodic_tol_(periodic_tolerance), every_cell_(d.local()),
      scheme_(scheme), bc_(boundary), fixup_(fixup) {
    for (int f = 0; f < 6; ++f)
        if (bc_.reflective[static_cast<size_t>(f)] && d.periodic(f / 2))
            throw Error(fmt::format("dom: face {} cannot be both reflective and periodic", kFaceNames[f]));
    // Mirror of every direction in each axis (Ω_a -> -Ω_a lands in octant o ^ (1 << a)).
    for (int a = 0; a < 3; ++a) {
        const bool needed = bc_.reflective[static_cast<size_t>(2 * a)] || bc_.reflective[static_cast<size_t>(2 * a + 1)];
        for (int o = 0; o < 8; ++o) {
            const auto& oc = ang.octants[static_cast<size_t>(o)];
            const auto& om = ang.octants[static_cast<size_t>(o ^ (1 << a))];
            auto& mirror = mirror_[static_cast<size_t>(a)][static_cast<size_t>(o)];
            mirror.assign(static_cast<size_t>(oc.size()), -1);
            for (int n = 0; n < oc.size(); ++n) {
                if (oc.abs_mu[static_cast<size_t>(a)][static_cast<size_t>(n)] == 0.0) continue;
                Vec3 w = oc.dir[static_cast<size_t>(n)];
                w[a] = -w[a];
                for (int m = 0; m < om.size(); ++m) {
                    const Vec3& v = om.dir[static_cast<size_t>(m)];
                    if (std::abs(v.x - w.x) + std::abs(v.y - w.y) + std::abs(v.z - w.z) < 1e-10)
                        mirror[static_cast<size_t>(n)] = m;
                }
                if (needed && mirror[static_cast<size_t>(n)] < 0)
                    throw Error(fmt::format("dom: reflective {} faces need a quadrature symmetric in {}; {} has no mirror "
                                            "of direction ({:.4f}, {:.4f}, {:.4f})", "xyz"[a], "xyz"[a],
                                            ang.quadrature.name, oc.dir[static_cast<size_t>(n)].x,
                                            oc.dir[static_cast<size_t>(n)].y, oc.dir[static_cast<size_t>(n)].z));
            }
        }
    }
    check_sweep_decomposition(d);
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
        const int blocks = scheme_ == SpatialScheme::diamond ? 4 : 1;  // [cell | x | y | z faces]
        if (nd > 0 && psi_.find(oc.size()) == psi_.end())
            psi_.emplace(oc.size(), Field<double>(d.local(), 1, blocks * oc.size(), 0.0));
    }
}

std::ptrdiff_t TransportSweeper::plane_index(int axis, int i, int j, int k) const {
    const Box& own = d_.local();
    const int idx[3] = {i, j, k};
    const int b1 = axis == 0 ? 1 : 0, b2 = axis == 2 ? 1 : 2;
    return static_cast<std::ptrdiff_t>(idx[b2] - own.lo[b2]) * own.size(b1) + (idx[b1] - own.lo[b1]);
}

std::optional<Box> TransportSweeper::region(const Field<double>& kappa, const SourceRows& rows) const {
    const Box b = bounding_box(d_, [&](int i, int j, int k) { return kappa(i, j, k) > 0.0 || rows.contains(i, j, k); });
    if (any_mirror() || b == d_.global()) return std::nullopt;
    return b;
}

bool TransportSweeper::any_mirror() const {
    return std::any_of(bc_.reflective.begin(), bc_.reflective.end(), [](bool r) { return r; });
}

void TransportSweeper::reset_reflections() {
    for (auto& face : reflected_)
        for (auto& plane : face) plane.clear();
    for (auto& c : mirror_current_) c.clear();
    for (auto& c : mirror_current_prev_) c.clear();
}

void TransportSweeper::reset_periodic_planes() {
    for (auto& axis : periodic_planes_)
        for (auto& plane : axis) plane.clear();
    periodic_rate_.fill(0.0);
}

void TransportSweeper::load_periodic_planes(Field<double>& psi, int o, bool from_zero) {
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const int nd = oc.size();
    static const std::vector<double> none;
    for (int a = 0; a < 2; ++a) {
        if (!d_.periodic(a)) continue;
        const std::vector<double>& buf = from_zero ? none : periodic_planes_[static_cast<size_t>(a)][static_cast<size_t>(o)];
        const int off = face_offset(a, nd);
        for_each_cell(upwind_ghost_plane(d_.local(), a, oc.octant.s[a]), [&](int i, int j, int k) {
            double* v = &psi(i, j, k) + off;
            if (buf.empty()) std::fill(v, v + nd, 0.0);
            else std::copy_n(buf.data() + plane_index(a, i, j, k) * nd, nd, v);
        });
    }
}

void TransportSweeper::store_periodic_planes(const Field<double>& psi, int o) {
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const int nd = oc.size();
    for (int a = 0; a < 2; ++a) {
        if (!d_.periodic(a)) continue;
        const Box p = upwind_ghost_plane(d_.local(), a, oc.octant.s[a]);
        std::vector<double>& buf = periodic_planes_[static_cast<size_t>(a)][static_cast<size_t>(o)];
        buf.resize(static_cast<size_t>(p.cells() * nd));
        const int off = face_offset(a, nd);
        for_each_cell(p, [&](int i, int j, int k) {
            const double* v = &psi(i, j, k) + off;
            std::copy_n(v, nd, buf.data() + plane_index(a, i, j, k) * nd);
        });
    }
}

void TransportSweeper::set_upwind_ghosts(Field<double>& psi, int o) {
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const Box& own = d_.local();
    const int nd = oc.size(), blocks = psi.ncomp() / nd;
    for (int a = 0; a < 3; ++a) {
        const int s = oc.octant.s[a];
        const bool at_boundary = s > 0 ? d_.at_low_boundary(a) : d_.at_high_boundary(a);
        // Interior faces are filled by the engine from upstream; periodic ones per layer.
        if (!at_boundary || d_.periodic(a)) continue;
        const int f = 2 * a + (s > 0 ? 0 : 1);  // the face this octant enters through
        const bool reflective = bc_.reflective[static_cast<size_t>(f)];
        const std::vector<double>& refl = reflected_[static_cast<size_t>(f)][static_cast<size_t>(o ^ (1 << a))];
        const std::vector<int>& mirror = mirror_[static_cast<size_t>(a)][static_cast<size_t>(o)];
        const bool sky = sky_on_ && !reflective && f != 4;
        // A vacuum face's plane is written only when it may hold something else: a field starts
        // at zero and only this function writes boundary ghost planes (rewriting the zeros every
        // sweep cost 10% of the DOM phase: a cache and TLB miss per cell of the x and y faces).
        bool& nonzero = ghost_nonzero_[psi.data()][static_cast<size_t>(f)];
        if (!reflective && !sky && !nonzero) continue;
        nonzero = reflective || sky;
        const double* mu = oc.abs_mu[static_cast<size_t>(a)].data();
        const Box p = upwind_ghost_plane(own, a, s);
        double power = 0.0;
        for_each_cell(p, [&](int i, int j, int k) {
            double* v = &psi(i, j, k);
            const double* r = reflective && !refl.empty() ? refl.data() + plane_index(a, i, j, k) * nd : nullptr;
            for (int n = 0; n < nd; ++n) {
                double in = 0.0;  // vacuum
                if (r) {
                    const int m = mirror[static_cast<size_t>(n)];
                    in = m >= 0 ? r[m] : 0.0;
                } else if (sky && oc.dir[static_cast<size_t>(n)].z < 0.0) {
                    in = sky_radiance_;
                }
                for (int b = 0; b < blocks; ++b) v[b * nd + n] = in;
                power += oc.weight[static_cast<size_t>(n)] * mu[n] * in;
            }
        });
        incoming_[static_cast<size_t>(f)] += h_ * h_ * power;
        if (sky) sky_incoming_ += h_ * h_ * power;
    }
}

void TransportSweeper::set_region_inflow(Field<double>& psi, int o, const Box& act, const Box& region) {
    if (act.empty()) return;
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const Box& g = d_.global();
    const int nd = oc.size(), blocks = psi.ncomp() / nd;
    for (int a = 0; a < 3; ++a) {
        const int s = oc.octant.s[a];
        // The region's upwind face: on the domain's face set_upwind_ghosts fills it; where the
        // region reaches on past this rank the upstream rank sends it.
        const int face = s > 0 ? region.lo[a] : region.hi[a];
        if (face == (s > 0 ? g.lo[a] : g.hi[a])) continue;
        if (face != (s > 0 ? act.lo[a] : act.hi[a])) continue;
        // Void all the way back to the domain's faces, none of them a mirror (region()): a
        // downward direction brings the sky radiance, an upward one comes from the vacuum below.
        for_each_cell(upwind_ghost_plane(act, a, s), [&](int i, int j, int k) {
            double* v = &psi(i, j, k);
            for (int n = 0; n < nd; ++n) {
                const double in = sky_on_ && oc.dir[static_cast<size_t>(n)].z < 0.0 ? sky_radiance_ : 0.0;
                for (int b = 0; b < blocks; ++b) v[b * nd + n] = in;
            }
        });
    }
}

void TransportSweeper::store_reflected(const Field<double>& psi, int o) {
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const Box& own = d_.local();
    const int nd = oc.size();
    for (int a = 0; a < 3; ++a) {
        const int s = oc.octant.s[a];
        const int f = 2 * a + (s > 0 ? 1 : 0);  // the face this octant leaves through
        const bool at_boundary = s > 0 ? d_.at_high_boundary(a) : d_.at_low_boundary(a);
        if (!at_boundary || !bc_.reflective[static_cast<size_t>(f)]) continue;
        Box p = own;
        p.lo[a] = s > 0 ? own.hi[a] - 1 : own.lo[a];
        p.hi[a] = p.lo[a] + 1;
        std::vector<double>& buf = reflected_[static_cast<size_t>(f)][static_cast<size_t>(o)];
        buf.resize(static_cast<size_t>(p.cells() * nd));
        const int off = face_offset(a, nd);
        std::vector<double>& current = mirror_current_[static_cast<size_t>(f)];  // high faces only
        if (s > 0) current.resize(static_cast<size_t>(p.cells()), 0.0);
        const double* mu = oc.abs_mu[static_cast<size_t>(a)].data();
        for_each_cell(p, [&](int i, int j, int k) {
            const double* v = &psi(i, j, k) + off;
            const std::ptrdiff_t c = plane_index(a, i, j, k);
            std::copy(v, v + nd, buf.data() + c * nd);
            if (s > 0) {
                double J = 0.0;
                for (int n = 0; n < nd; ++n) J += oc.weight[static_cast<size_t>(n)] * mu[n] * v[n];
                current[static_cast<size_t>(c)] += J;
            }
        });
    }
}

void TransportSweeper::reduce_octant(const Field<double>& psi, int o, const Box& act, SweepOutput& out) {
    const auto& oc = ang_.octants[static_cast<size_t>(o)];
    const int nd = oc.size();
    const Box& own = act;  // the swept cells
    const Box& g = d_.global();
    const double area = h_ * h_;
    // Leakage: the outgoing face values of the cells on the domain's downwind faces.
    for (int a = 0; a < 3; ++a) {
        if (d_.periodic(a)) continue;
        const int s = oc.octant.s[a];
        const int edge = s > 0 ? g.hi[a] - 1 : g.lo[a];
        if (edge < own.lo[a] || edge >= own.hi[a]) continue;
        Box plane = own;
        plane.lo[a] = edge;
        plane.hi[a] = edge + 1;
        const double* mu = oc.abs_mu[static_cast<size_t>(a)].data();
        double& leakage = out.leakage[static_cast<size_t>(2 * a + (s > 0 ? 1 : 0))];
        for_each_cell(plane, [&](int i, int j, int k) {
            const double* face = &psi(i, j, k) + face_offset(a, nd);  // outgoing face values
            double leak = 0.0;
            for (int n = 0; n < nd; ++n) leak += oc.weight[static_cast<size_t>(n)] * mu[n] * face[n];
            leakage += area * leak;
        });
    }
}

void TransportSweeper::sweep(const SweepSource& src, SweepOutput& out) {
    const Box& own = d_.local();
    const SourceRows& rows = src.rows ? *src.rows : every_cell_;
    const int nmom = ang_.nmom;
    const size_t packed = rows.cells() * static_cast<size_t>(nmom);
    check_collective(d_.comm(), rows.box() == own && src.moments.size() == packed,  // else a caller's bug
                     fmt::format("dom: the sweep's source rows or moments do not fit this rank's box ({} moments "
                                 "for {} source cells x {})", src.moments.size(), rows.cells(), nmom));
    // The cells swept: act, this rank's part of the region (SweepSource::region).
    const Box region = src.region ? *src.region : d_.global();
    const Box act = own.intersect(region);
    bool spans_inside = true;  // the source rows lie in the region
    for (int k = own.lo[2]; k < own.hi[2]; ++k)
        for (int j = own.lo[1]; j < own.hi[1]; ++j)
            if (rows.hi(j, k) > rows.lo(j, k) && !(act.contains(rows.lo(j, k), j, k) && act.contains(rows.hi(j, k) - 1, j, k)))
                spans_inside = false;
    check_collective(d_.comm(), !src.region || (!any_mirror() && spans_inside),  // else a caller's bug
                     "dom: a sweep confined to a region needs every source cell inside it and no reflective face");
    ++timing_.sweeps;
    timing_.swept_cells += static_cast<double>(region.intersect(d_.global()).cells());
    out.phi.resize(packed);  // overwritten by the first group_moments
    if (out.fluence.owned() != own) {
        out.fluence = Field<double>(own, 0, 1, 0.0);
        out.flux = Field<double>(own, 0, 3, 0.0);
    }
    bool first_group = true;
    out.leakage.fill(0.0);
    out.min_psi = std::numeric_limits<double>::infinity();
    incoming_.fill(0.0);
    sky_incoming_ = 0.0;
    for (size_t f = 1; f < 6; f += 2) {  // this sweep's outgoing currents start from zero
        std::swap(mirror_current_[f], mirror_current_prev_[f]);
        std::fill(mirror_current_[f].begin(), mirror_current_[f].end(), 0.0);
    }
    sky_on_ = bc_.sky && src.amp != nullptr;
    const bool fixup = fixup_ && src.amp != nullptr;  // not on GMRES's operator sweeps (must stay linear)
    // Periodic planes start from this octant's previous sweep only on sweeps with the external
    // sources (source iteration, DSA, GMRES's right-hand side and final sweep): GMRES's operator
    // sweeps of Krylov vectors start from zero, so that K(v) does not depend on the vector swept
    // before (whose planes may be of any size: the stopping test is relative to the largest edge
    // value, stale ones included) and K(0) = 0.
    const bool external = src.amp != nullptr;
    const double* kap = src.kappa->data();
    // Octants in groups swept at once (octant_groups above; a group of one is the plain KBA
    // sweep). Slot q of a group holds octant group[q]: its psi field (slot 0: psi_, others:
    // overlap_psi_) and its source (source_, overlap_source_).
    const bool diamond = scheme_ == SpatialScheme::diamond;
    const bool periodic = d_.periodic(0) || d_.periodic(1);
    auto cell_kernel = [&](OctantSlot& sl, int i, int j, int k) {
        const std::ptrdiff_t cell = cell_offset(own, i, j, k);
        const int nd = sl.nd;
        const double* S = sl.source->values.data() + cell * nd;
        double* p = sl.psi->data() + sl.psi->index(i, j, k);
        if (diamond)
            sl.fixups += diamond_cell(nd, kap[cell], S, sl.cx, sl.cy, sl.cz, p - sl.ox + sl.fx, p - sl.oy + sl.fy,
                                      p - sl.oz + sl.fz, p, p + sl.fx, p + sl.fy, p + sl.fz, fixup);
        else
            step_cell(nd, kap[cell], S, sl.cx, sl.cy, sl.cz, sl.cs, p - sl.ox, p - sl.oy, p - sl.oz, p);
    };
    // Periodic x/y: the engine sweeps whole z layers (one tile); after the last cell of a
    // layer, the layer's periodic ghosts g are set from its downwind edges e and the layer is
    // recomputed until they agree (local: no communication; each octant's planes start from its
    // previous sweep, load_periodic_planes). The step scheme takes g = e: a ghost's error reaches
    // the edge through factors c_x / (kappa + c_x + c_y + c_z) in [0, 1), a plain contraction.
    // Diamond's face relation out = 2 psi - in gives factors (c_x - c_y - c_z) / (c_x + c_y + c_z)
    // in thin cells (-> -1 for directions nearly normal to the axis), so errors alternate in sign
    // and, with the fix-up switching, plain passes can 2-cycle (a sky-lit absorber slab at S8).
    // Diamond therefore takes g from Anderson acceleration of the map g -> e (src/core/anderson.h,
    // depth 5, no damping, this rank's values only). Measured passes per layer (test
    // PeriodicLayersConvergeInFewPassesWhereTheLightIsZero): a fixed weight g += w (e - g) gave
    // 25.7 (w = 1), 9.1 (0.7), 12.8 (0.5, used until the twenty-eighth session), 17.0 (0.4); a
    // secant weight per value 15.1; Anderson 5.7. For the step scheme Anderson took more passes
    // than g = e (slab 3856 against 3460, default cloud periodic in x and y 8064 against 7499).
    // The test is relative to the largest edge value of any pass of this layer, not of the last
    // one: where the layer's answer is 0 (upward directions under the medium) but its start is
    // not, the change and the edge values fall geometrically together with a constant ratio,
    // which took ~185 passes to underflow on a quarter of the slab's layers.
    auto periodic_layer = [&](OctantSlot& sl, int k) {
        Field<double>& psi = *sl.psi;
        const int nd = sl.nd;
        // Visits the layer's periodic ghost values and the edge values they must equal (on the
        // swept cells: a region spans periodic axes whole).
        auto for_each_ghost = [&](auto&& f) {
            for (int a = 0; a < 2; ++a) {
                if (!d_.periodic(a)) continue;
                const int s = sl.octant.s[a];
                const int ghost = upwind_ghost_plane(act, a, s).lo[a], edge = s > 0 ? act.hi[a] - 1 : act.lo[a];
                for (int t = act.lo[1 - a]; t < act.hi[1 - a]; ++t)
                    f((a == 0 ? &psi(ghost, t, k) : &psi(t, ghost, k)) + face_offset(a, nd),
                      (a == 0 ? &psi(edge, t, k) : &psi(t, edge, k)) + face_offset(a, nd));
            }
        };
        std::optional<AndersonMixer> mixer;  // diamond, from the first pass that continues
        double scale = 0.0, previous = 0.0;
        double& rate = periodic_rate_[static_cast<size_t>(sl.o)];
        for (int pass = 0;; ++pass) {
            sl.ghosts.clear();
            sl.edges.clear();
            for_each_ghost([&](const double* g, const double* e) {
                sl.ghosts.insert(sl.ghosts.end(), g, g + nd);
                sl.edges.insert(sl.edges.end(), e, e + nd);
            });
            double change = 0.0;
            for (size_t v = 0; v < sl.ghosts.size(); ++v) {
                change = std::max(change, std::abs(sl.edges[v] - sl.ghosts[v]));
                scale = std::max(scale, std::abs(sl.edges[v]));
            }
            // Step: g = e is a contraction of rate rho, so the ghosts are within change rho / (1 - rho)
            // of the layer's fixed point, not within `change`: where rho is near 1 (a layer one cell
            // wide along a periodic axis, lit by directions nearly along it: the ghost feeds the
            // same cell) stopping at a small change left an error 1/(1 - rho) larger, a floor under
            // which DSA could not converge (stalled at 6.7e-4 on the slab at 16 x 1 x 64 cells; a QA
            // finding). rho is the largest ratio of successive changes this octant has shown (so
            // a first pass that already meets the test knows it too).
            if (!diamond && pass > 0 && previous > 0.0) rate = std::max(rate, std::min(change / previous, 0.999));
            previous = change;
            const double amplify = diamond ? 1.0 : std::max(1.0, rate / (1.0 - rate));
            const bool done = change * amplify <= periodic_tol_ * scale;
            if (!done && pass >= kMaxPeriodicPasses) {
                periodic_failure_ = std::max(periodic_failure_, change / scale);
                return;
            }
            if (diamond && !done) {
                if (!mixer) mixer.emplace(MPI_COMM_SELF, kPeriodicAndersonDepth, 1.0);
                sl.edges = mixer->next(sl.ghosts, sl.edges);  // now the next ghosts
            }
            size_t v = 0;
            for_each_ghost([&](double* g, const double*) {
                std::copy_n(sl.edges.data() + v, nd, g);
                v += static_cast<size_t>(nd);
            });
            if (done) return;
            ++timing_.periodic_passes;
            for (int j = sl.ry.first; j != sl.ry.end; j += sl.ry.step)
                for (int i = sl.rx.first; i != sl.rx.end; i += sl.rx.step) cell_kernel(sl, i, j, k);
        }
    };
    auto kernel = [&](OctantSlot& sl, int i, int j, int k) {
        cell_kernel(sl, i, j, k);
        if (periodic && i == sl.last_i && j == sl.last_j) periodic_layer(sl, k);
    };
    for (const std::vector<int>& group : octant_groups(opt_.octant_overlap, bc_.reflective)) {
        std::vector<OctantSlot> slots;
        if (overlap_psi_.size() + 1 < group.size()) {  // before taking pointers into them
            overlap_psi_.resize(group.size() - 1);
            overlap_source_.resize(group.size() - 1);
        }
        for (int o : group) {
            const auto& oc = ang_.octants[static_cast<size_t>(o)];
            const int nd = oc.size();
            if (nd == 0) continue;
            OctantSlot sl;
            sl.o = o;
            sl.nd = nd;
            sl.octant = oc.octant;
            const size_t q = slots.size();
            Field<double>& by_size = psi_.at(nd);
            if (q == 0) {
                sl.psi = &by_size;
                sl.source = &source_;
            } else {
                Field<double>& f = overlap_psi_[q - 1];
                if (f.owned() != own || f.ncomp() != by_size.ncomp()) f = Field<double>(own, 1, by_size.ncomp(), 0.0);
                sl.psi = &f;
                sl.source = &overlap_source_[q - 1];
            }
            const auto& c = coef_[static_cast<size_t>(o)];
            sl.cx = c[0].data();
            sl.cy = c[1].data();
            sl.cz = c[2].data();
            sl.cs = c[3].data();
            sl.ox = oc.octant.s[0] * sl.psi->stride(0);
            sl.oy = oc.octant.s[1] * sl.psi->stride(1);
            sl.oz = oc.octant.s[2] * sl.psi->stride(2);
            sl.fx = face_offset(0, nd);
            sl.fy = face_offset(1, nd);
            sl.fz = face_offset(2, nd);
            sl.rx = sweep::upwind_range(act, 0, oc.octant);
            sl.ry = sweep::upwind_range(act, 1, oc.octant);
            sl.last_i = sl.rx.end - sl.rx.step;
            sl.last_j = sl.ry.end - sl.ry.step;
            slots.push_back(sl);
        }
        if (slots.empty()) continue;
        // Sources first (group_sources), so that repeated periodic passes only redo the cheap
        // transport kernel.
        const double t_src = MPI_Wtime();
        group_sources(own, src, rows, ang_, slots);
        timing_.moment_seconds += MPI_Wtime() - t_src;
        for (OctantSlot& sl : slots) {
            set_upwind_ghosts(*sl.psi, sl.o);
            set_region_inflow(*sl.psi, sl.o, act, region);
            if (periodic) load_periodic_planes(*sl.psi, sl.o, !external);
        }
        const double t0 = MPI_Wtime();
        sweep::SweepStats stats;
        if (slots.size() == 1) {
            OctantSlot& sl = slots[0];
            stats = sweep::run(d_, *sl.psi, sl.octant, opt_, [&](int i, int j, int k) { kernel(sl, i, j, k); },
                               region);
        } else {
            std::vector<Field<double>*> fields;
            std::vector<sweep::Octant> octants;
            for (OctantSlot& sl : slots) {
                fields.push_back(sl.psi);
                octants.push_back(sl.octant);
            }
            stats = sweep::run_octants(d_, fields, octants, opt_,
                                       [&](int q, int i, int j, int k) { kernel(slots[static_cast<size_t>(q)], i, j, k); },
                                       region);
        }
        timing_.sweep_seconds += MPI_Wtime() - t0;
        timing_.wait_seconds += stats.wait_seconds;
        for (OctantSlot& sl : slots) {
            timing_.fixups += sl.fixups;
            store_reflected(*sl.psi, sl.o);
            if (periodic && external) store_periodic_planes(*sl.psi, sl.o);
            out.min_psi = std::min(out.min_psi, min_over(*sl.psi, act));
        }
        const double t1 = MPI_Wtime();
        group_moments(own, act, ang_, slots, rows, out, first_group);
        first_group = false;
        timing_.moment_seconds += MPI_Wtime() - t1;
        for (OctantSlot& sl : slots) reduce_octant(*sl.psi, sl.o, act, out);  // leakage
    }
    if (first_group) {  // no octant had directions: nothing was written
        std::fill(out.phi.begin(), out.phi.end(), 0.0);
        out.fluence.fill(0.0);
        out.flux.fill(0.0);
    }
    std::array<double, 7> power{};  // net leakage per face, then the sky's incoming power
    for (size_t f = 0; f < 6; ++f) power[f] = out.leakage[f] - incoming_[f];
    power[6] = sky_incoming_;
    MPI_Allreduce(MPI_IN_PLACE, power.data(), 7, MPI_DOUBLE, MPI_SUM, d_.comm());
    std::copy_n(power.begin(), 6, out.leakage.begin());
    out.sky_incoming = power[6];
    const double failure = periodic_failure_;
    periodic_failure_ = 0.0;
    check_collective(d_.comm(), failure == 0.0,
                     fmt::format("dom: periodic boundary planes did not converge in {} passes (relative change {:.3e})",
                                 kMaxPeriodicPasses, failure));
}

}  // namespace nimbus::dom
