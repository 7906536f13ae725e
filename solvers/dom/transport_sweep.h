// One transport sweep of the diffuse radiance over all directions: for each octant, the
// direction group of the octant is swept through the domain on the shared KBA engine
// (solvers/sweep/sweep.h; ncomp = the octant's directions), then its angular flux is reduced
// to moments. Only the moments, one octant's angular flux and its source are stored (plus the
// periodic boundary planes, per octant).
//
// Octant overlap (SweepOptions::octant_overlap = [model.dom] octant_overlap): with 2, the +z/-z
// pairs with equal x/y signs, with 8 all octants, are swept at once on the engine's
// run_octants (data-driven: a rank computes whichever octant's next tile has its upstream
// plane), so a +z and a -z octant run from the opposite ends of the slab chain and the
// pipeline fill of one is covered by the other's work. Memory: one psi field and one source
// per octant in flight. A reflective z- face limits the overlap to 1 and a reflective x- or y-
// face limits 8 to 2 (the mirrored octant must finish first, see below). Periodic x/y sweeps
// overlap too: each octant's periodic planes start from its own previous sweep, so the
// result does not depend on the overlap.
//
// Spatial scheme (cell_kernel.h): step, psi stored as one value per direction and cell
// (ncomp = nd, the upwind cell's value is the incoming face value); or diamond difference with
// fix-up, which needs the outgoing FACE value per axis: psi then holds 4 blocks of nd values
// per cell, [cell | x face | y face | z face] (ncomp = 4 nd). This keeps the engine's contract
// (the downwind cell reads its upwind neighbour's storage: block 1 + a along axis a) with one
// field and one halo plane, at the price of sending 4 nd values per boundary cell where nd
// would do (the engine packs whole cells); the cell block stays first so the moment reduction
// reads psi(i, j, k)[n] for either scheme.
//
// Domain-face boundaries (SweepBoundary; faces x-, x+, y-, y+, z-, z+):
// - vacuum: zero incoming radiance (default);
// - reflective (specular): psi_in(Ω) = psi_out(Ω') with Ω' = Ω mirrored in the face, taken
//   from the mirrored direction of octant o ^ (1 << axis) (the constructor checks that the
//   quadrature has every mirror). Octants are swept in the order 0..7 (bit a set = moving
//   toward +a), so at a LOW face (x-, y-, z-) the mirrored octant is done earlier in the same
//   sweep (exact); at a HIGH face it is the previous sweep's (lagged one sweep: converged by the
//   outer source/DSA iteration, not a linear operator for GMRES). Requires that octant
//   o ^ (1 << a) finishes on this rank before octant o starts when bit a of o is set.
// - sky: a uniform incoming radiance L (set_sky_radiance, per band) for every downward
//   direction (Ω_z < 0) entering through the top face or a side face (vacuum for upward ones),
//   on the non-reflective, non-periodic faces. Applied only on sweeps that carry the external
//   sources (src.amp != nullptr), so GMRES's scattering-only operator sweeps stay homogeneous.
//   Likewise the diamond fix-up: it acts only on those sweeps (a physical radiance); GMRES's
//   operator sweeps of Krylov vectors, which may be negative, stay linear.
// - periodic x/y (Decomposition::periodic), by iterating the boundary planes layer by layer:
// the engine sweeps whole z layers, and after a layer is done its upwind ghost columns/rows are
// set to its downwind edges (step) or to an Anderson-accelerated step toward them (diamond, see
// sweep()) and the layer is recomputed until they change by less than
// `periodic_tolerance` (relative to the layer's largest edge value, max norm). On sweeps with
// the external sources each octant's ghost planes start from where its previous such sweep
// left them (kept per octant), so once source iteration or DSA settles a layer needs one or two
// passes; GMRES's operator sweeps start from zero. Local work only, no extra communication.
// Periodic axes must not be split over ranks.
//
// Region (SweepSource::region, from region()): a sweep may cover only the bounding box of the
// cells with extinction or a source. Outside it is void, so the light that enters the box is the
// boundary's, carried unchanged (vacuum; with the sky radiance, L for downward directions, since
// traced back every such ray ends on the top or a side face) and the light that leaves never
// returns (no mirror faces; periodic axes are taken whole). Inside, the sweep then equals the
// whole domain's (tests/unit/sweep_engine/dom_region_test.cpp: to 1e-13, after a whole sweep
// too, on 1-3 ranks, regions that miss ranks or start on a slab boundary). The engine sweeps the
// region's part of each rank (sweep.h); the cells just upwind of it that no rank sends are set
// here (set_region_inflow). The outer iterations sweep the region, the last sweep the domain
// (iteration.h, gmres.h): on the default cloud the box is 36% of the grid and the engine time of
// the DOM phase fell 2.1x (solvers/dom/README.md, "Sweeping the medium's box").
//
// Outputs per sweep (owned cells): the moments phi_k = Σ_n w_n Y_k(Ω_n) psi_n (of the cells of
// the source rows, SweepSource::rows, packed), the fluence
// Σ_n w_n psi_n (W/m²), the flux Σ_n w_n Ω_n psi_n, and the NET power leaving through each
// non-periodic domain face, Σ_faces h² Σ_n w_n |Ω·n| (psi_out,face - psi_in,face) (W; face
// value = cell value for the step scheme, the outgoing face value for diamond; psi_in = 0 on
// vacuum faces), order x-, x+, y-, y+, z-, z+; summed over ranks; and the power the sky radiance
// brought in (sky faces only, not mirrored light), summed over ranks.
//
// Collective over d.comm(). Not thread-safe. The Decomposition and AngularSet must outlive it.
#pragma once

#include <array>
#include <initializer_list>
#include <map>
#include <optional>
#include <span>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/sweep/sweep.h"
#include "src/core/bounding_box.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus::dom {

// The cells of each x row of the owned box where a sweep's source can be nonzero: [lo, hi)
// spans the row's cells with a nonzero value in any of the given fields (for a band problem:
// sigma_s, emission and the first-collision amplitudes; band_problem.h). Outside the spans the
// source is zero and the moments phi are neither computed nor stored: their only use is the
// scattering source sigma_s phi, zero there. So a sweep builds sources and moments on the spans
// and only the fluence and flux elsewhere (1 of 5 vector FMAs per direction and cell at L = 3),
// and moments are stored packed: nmom values per span cell, in for_each_cell's order. On the
// default cloud the spans hold 12% of the cells.
class SourceRows {
public:
    SourceRows() = default;
    SourceRows(const Box& own, std::initializer_list<const Field<double>*> fields);
    explicit SourceRows(const Box& own);  // every cell of own
    // Span of row (j, k), in x cell indices; lo == hi when the row has none.
    int lo(int j, int k) const { return lo_[row(j, k)]; }
    int hi(int j, int k) const { return hi_[row(j, k)]; }
    bool contains(int i, int j, int k) const { return i >= lo(j, k) && i < hi(j, k); }
    // Share of the owned cells inside the spans.
    double fraction() const;
    const Box& box() const { return own_; }
    bool operator==(const SourceRows& o) const { return own_ == o.own_ && lo_ == o.lo_ && hi_ == o.hi_; }
    // Number of cells inside the spans.
    size_t cells() const;
    // Calls f(c, q) for every cell inside the spans, in increasing order: c is the cell's offset
    // in a ghost-free field on own (x fastest), q = 0, 1, ... its place among the span cells
    // (the index into storage packed to the spans, as GMRES's vectors are).
    template <class F>
    void for_each_cell(F&& f) const {
        size_t q = 0;
        for (int k = own_.lo[2]; k < own_.hi[2]; ++k)
            for (int j = own_.lo[1]; j < own_.hi[1]; ++j) {
                const size_t r = row(j, k), first = r * static_cast<size_t>(own_.size(0));
                for (int i = lo_[r]; i < hi_[r]; ++i) f(first + static_cast<size_t>(i - own_.lo[0]), q++);
            }
    }

private:
    size_t row(int j, int k) const {
        return static_cast<size_t>(k - own_.lo[2]) * static_cast<size_t>(own_.size(1)) +
               static_cast<size_t>(j - own_.lo[1]);
    }
    Box own_;
    std::vector<int> lo_, hi_;
};

// One octant's source in the sweeper, cells x nd (+3, moment_kernels.h), and what is known of
// it: zero outside the spans of zero_rows when set (it was last written with those rows and
// this nd), so a sweep with the same rows need not zero those cells again.
struct SourceBuffer {
    std::vector<double> values;
    std::optional<SourceRows> zero_rows;
    int nd = 0;
};

// Per-band inputs of a sweep, all on d.local() with no ghost layer. Non-owning.
struct SweepSource {
    const Field<double>* kappa = nullptr;    // kappa* (1/m), 1 component
    // s_k = kappa* a* chi_l(k) phi_k (+ emission): nmom values per cell of the source rows below,
    // packed in SourceRows::for_each_cell order (every owned cell, x fastest, when rows is null).
    std::span<const double> moments;
    const Field<double>* amp = nullptr;      // first-collision amplitudes A_l, nl components (nl may be 0)
    int nl = 0;
    // Per octant: nl x nd phase values P_l,n (cell_kernel.h).
    std::array<std::vector<double>, 8> light_phase;
    // Where the source can be nonzero (above), on d.local(); null: every cell. Must cover every
    // cell where amp is nonzero (the first-collision source of this sweep) and every cell where
    // kappa* a* is (where the next source needs phi, which exists on the rows only).
    const SourceRows* rows = nullptr;
    // The cells the sweep computes (global cells; null: the whole domain), from
    // TransportSweeper::region: they hold every cell with extinction or a source, so everything
    // outside is void and the light crossing it is known without a sweep: what enters the
    // region is the boundary's (vacuum, or the sky radiance for downward directions) and what
    // leaves it streams out of the domain without coming back. Inside, the sweep equals the
    // whole domain's. Outside, phi, fluence and flux are 0, and the leakage counts only the
    // region's cells on the domain's faces: the outer iterations sweep the region, and one last
    // sweep of the whole domain gives the fields.
    const Box* region = nullptr;
};

struct SweepOutput {
    std::vector<double> phi;  // nmom per cell of the sweep's source rows, packed like SweepSource::moments
    Field<double> fluence;  // 1 component
    Field<double> flux;     // 3 components
    std::array<double, 6> leakage{};
    double sky_incoming = 0;  // power the sky radiance brought in through the faces, W, all ranks
    double min_psi = 0;     // smallest cell or face angular flux of the swept cells, this rank
};

enum class SpatialScheme { step, diamond };

// Domain-face boundary conditions, faces x-, x+, y-, y+, z-, z+ (periodic axes come from the
// Decomposition). A face must not be reflective on a periodic axis.
struct SweepBoundary {
    std::array<bool, 6> reflective{};
    bool sky = false;  // uniform incoming sky radiance on the top and side faces (see above)
};

struct SweepTiming {
    double sweep_seconds = 0;     // engine time (kernel + pipeline), this rank
    double wait_seconds = 0;      // of which blocked on upstream planes
    double moment_seconds = 0;    // moments to directions (source) and back (reduction)
    int periodic_passes = 0;      // extra layer passes of the periodic iteration
    std::int64_t fixups = 0;      // diamond: cell-directions that needed the negative-flux fix-up
    int sweeps = 0;               // sweeps made
    double swept_cells = 0;       // global cells they covered (the region's, or the domain's), summed
};

// What the sweeper needs of the decomposition: periodic x/y unsplit, z not periodic. Throws
// Error on every rank alike; run by the model's pre-flight check and by the constructor.
void check_sweep_decomposition(const Decomposition& d);

class TransportSweeper {
public:
    // Throws Error (same on every rank) when a reflective face is on a periodic axis or the
    // quadrature lacks a mirrored direction. fixup = false: plain diamond (tests only).
    TransportSweeper(const Decomposition& d, const AngularSet& ang, double h,
                     const sweep::SweepOptions& opt, double periodic_tolerance,
                     SpatialScheme scheme = SpatialScheme::step, const SweepBoundary& boundary = {},
                     bool fixup = true);
    // Collective. out is (re)allocated on d.local() when needed and overwritten.
    void sweep(const SweepSource& src, SweepOutput& out);
    // Collective. The region SweepSource::region may confine the sweeps of a problem with
    // extinction kappa and sources on rows to (global cells): the bounding box of the cells with
    // kappa > 0 or in rows, over all ranks, whole along periodic axes; empty when there are none.
    // Null when it would be the whole domain, or when a face is reflective (a mirror returns
    // light that left the region).
    std::optional<Box> region(const Field<double>& kappa, const SourceRows& rows) const;
    const SweepTiming& timing() const { return timing_; }
    const SweepBoundary& boundary() const { return bc_; }
    // Uniform sky radiance L (W/m²/sr) of the current band for SweepBoundary::sky.
    void set_sky_radiance(double L) { sky_radiance_ = L; }
    // Forgets the lagged reflected planes (zero), e.g. before a new band.
    void reset_reflections();
    // Forgets the periodic planes' starting guesses (below), e.g. before a new band: its first
    // sweep starts from zero.
    void reset_periodic_planes();
    // A HIGH mirror face returns the previous sweep's outgoing light (a low one the same
    // sweep's): calls f(i, j, k, dJ) for each of this rank's boundary cells on a high
    // reflective face, dJ = outgoing current of the last sweep minus that of the one before
    // (W/m², Σ w |Ω·n| psi over the leaving directions): the change of the incoming current the
    // next sweep will see there, which DSA adds as a boundary source (dsa.h).
    template <class F>
    void for_each_lagged_mirror_change(F&& f) const {
        for (int a = 0; a < 3; ++a) {
            const size_t face = static_cast<size_t>(2 * a + 1);
            if (!bc_.reflective[face] || !d_.at_high_boundary(a)) continue;
            const std::vector<double>& now = mirror_current_[face];
            const std::vector<double>& before = mirror_current_prev_[face];
            Box p = d_.local();
            p.lo[a] = p.hi[a] - 1;
            for_each_cell(p, [&](int i, int j, int k) {
                const auto c = static_cast<size_t>(plane_index(a, i, j, k));
                f(i, j, k, (c < now.size() ? now[c] : 0.0) - (c < before.size() ? before[c] : 0.0));
            });
        }
    }

private:
    bool any_mirror() const;  // a reflective face
    void set_upwind_ghosts(Field<double>& psi, int o);
    // The cells just upwind of the part act of a region (SweepSource::region) that no rank
    // sweeps: vacuum, or the sky radiance for downward directions on sweeps that carry it.
    void set_region_inflow(Field<double>& psi, int o, const Box& act, const Box& region);
    void store_reflected(const Field<double>& psi, int o);
    void load_periodic_planes(Field<double>& psi, int o, bool from_zero);  // upwind periodic ghosts of octant o
    void store_periodic_planes(const Field<double>& psi, int o);  // ... after its sweep
    void reduce_octant(const Field<double>& psi, int o, const Box& act, SweepOutput& out);  // leakage of octant o
    int face_offset(int axis, int nd) const { return scheme_ == SpatialScheme::diamond ? (1 + axis) * nd : 0; }
    std::ptrdiff_t plane_index(int axis, int i, int j, int k) const;

    const Decomposition& d_;
    const AngularSet& ang_;
    double h_;
    sweep::SweepOptions opt_;
    double periodic_tol_;
    double periodic_failure_ = 0.0;  // relative change left where a layer did not converge
    // Per octant, the step scheme's slowest contraction rate of the periodic layer iteration
    // seen since reset_periodic_planes (its stopping test, sweep()).
    std::array<double, 8> periodic_rate_{};
    SourceRows every_cell_;          // the rows of a SweepSource without rows
    std::map<int, Field<double>> psi_;                          // by octant size
    std::array<std::array<std::vector<double>, 4>, 8> coef_;    // cx, cy, cz, csum per octant
    SourceBuffer source_;  // one octant's source
    // Octants in flight beyond the first (octant_overlap 2 or 8, slot q >= 1): psi and source.
    std::vector<Field<double>> overlap_psi_;
    std::vector<SourceBuffer> overlap_source_;
    SweepTiming timing_;
    SpatialScheme scheme_;
    SweepBoundary bc_;
    bool fixup_;
    double sky_radiance_ = 0.0;
    bool sky_on_ = false;  // this sweep applies the sky radiance
    // mirror_[a][o][n]: index in octant o ^ (1 << a) of direction n of octant o mirrored in axis
    // a (-1 when |Ω_a| = 0: nothing enters along a).
    std::array<std::array<std::vector<int>, 8>, 3> mirror_;
    // reflected_[f][o]: outgoing face values of the boundary plane of face f (reflective, on
    // this rank) for the octant o leaving through it, plane cells x nd.
    std::array<std::array<std::vector<double>, 8>, 6> reflected_;
    // periodic_planes_[a][o]: the upwind ghost plane of periodic axis a (x or y) as octant o's
    // last sweep left it (plane cells x nd, face values), the start of its next sweep's layer
    // iteration; empty: zero.
    std::array<std::array<std::vector<double>, 8>, 2> periodic_planes_;
    std::array<double, 6> incoming_{};  // power entering through each face in this sweep (W)
    double sky_incoming_ = 0.0;         // of which the sky radiance's, all faces (W)
    // Per psi buffer (its data pointer) and face: whether set_upwind_ghosts may have left a
    // non-zero value in that boundary ghost plane (sky or mirror), so a vacuum face must clear it.
    std::map<const double*, std::array<bool, 6>> ghost_nonzero_;
    // Outgoing current per boundary cell of each high reflective face (plane_index order), this
    // sweep and the one before (for_each_lagged_mirror_change).
    std::array<std::vector<double>, 6> mirror_current_, mirror_current_prev_;
};

}  // namespace nimbus::dom
