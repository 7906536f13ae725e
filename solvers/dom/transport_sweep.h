// One transport sweep of the diffuse radiance over all directions: for each octant, the
// direction group of the octant is swept through the domain on the shared KBA engine
// (solvers/sweep/sweep.h; ncomp = the octant's directions), then its angular flux is reduced
// to moments. Only the moments, one octant's angular flux and its source are stored (plus the
// periodic boundary planes, per octant).
//
// Boundaries: vacuum (zero incoming radiance) on non-periodic domain faces; periodic x/y
// (Decomposition::periodic) by iterating the boundary planes layer by layer: the engine sweeps
// whole z layers, and after a layer is done its upwind ghost columns/rows are set to its
// downwind edges and the layer is recomputed until they change by less than
// `periodic_tolerance` (relative, max norm). Local work only, no extra communication.
// Periodic axes must not be split over ranks.
//
// Outputs per sweep (owned cells): the moments phi_k = Σ_n w_n Y_k(Ω_n) psi_n, the fluence
// Σ_n w_n psi_n (W/m²), the flux Σ_n w_n Ω_n psi_n, and the power leaving through each
// non-periodic domain face, Σ_faces h² Σ_{Ω·n>0} w_n |Ω·n| psi_face (W; face value = cell value
// for the step scheme), order x-, x+, y-, y+, z-, z+; summed over ranks.
//
// Collective over d.comm(). Not thread-safe. The Decomposition and AngularSet must outlive it.
#pragma once

#include <array>
#include <map>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/sweep/sweep.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus::dom {

// Per-band inputs of a sweep, all on d.local() with no ghost layer. Non-owning.
struct SweepSource {
    const Field<double>* kappa = nullptr;    // kappa* (1/m), 1 component
    const Field<double>* moments = nullptr;  // s_k = kappa* a* chi_l(k) phi_k (+ emission), nmom components
    const Field<double>* amp = nullptr;      // first-collision amplitudes A_l, nl components (nl may be 0)
    int nl = 0;
    // Per octant: nl x nd phase values P_l,n (cell_kernel.h).
    std::array<std::vector<double>, 8> light_phase;
};

struct SweepOutput {
    Field<double> phi;      // nmom components
    Field<double> fluence;  // 1 component
    Field<double> flux;     // 3 components
    std::array<double, 6> leakage{};
};

struct SweepTiming {
    double sweep_seconds = 0;     // engine time (kernel + pipeline), this rank
    double wait_seconds = 0;      // of which blocked on upstream planes
    double moment_seconds = 0;    // moments to directions (source) and back (reduction)
    std::int64_t cell_directions = 0;  // cells x directions computed by this rank (incl. periodic passes)
    int periodic_passes = 0;      // extra layer passes of the periodic iteration
};

class TransportSweeper {
public:
    TransportSweeper(const Decomposition& d, const AngularSet& ang, double h,
                     const sweep::SweepOptions& opt, double periodic_tolerance);
    // Collective. out is (re)allocated on d.local() when needed and overwritten.
    void sweep(const SweepSource& src, SweepOutput& out);
    const SweepTiming& timing() const { return timing_; }

private:
    void set_upwind_ghosts(Field<double>& psi, int o);
    void reduce_octant(const Field<double>& psi, int o, SweepOutput& out);

    const Decomposition& d_;
    const AngularSet& ang_;
    double h_;
    sweep::SweepOptions opt_;
    double periodic_tol_;
    double periodic_failure_ = 0.0;  // relative change left where a layer did not converge
    std::map<int, Field<double>> psi_;                          // by octant size
    std::array<std::array<std::vector<double>, 4>, 8> coef_;    // cx, cy, cz, csum per octant
    std::vector<double> source_;  // one octant's source, cells x directions
    SweepTiming timing_;
};

}  // namespace nimbus::dom
