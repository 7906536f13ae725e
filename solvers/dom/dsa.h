// Diffusion synthetic acceleration (Alcouffe 1977; Adams & Larsen 2002 §4) on the diffusion
// model's cell-centred hypre assembly (solvers/diffusion: Assembler, solve_with_hypre).
// After a transport sweep has produced the fluence phi^{l+1/2} from phi^l, the error of the
// isotropic part is estimated by the diffusion problem
//   -∇·(D ∇δ) + sigma_a δ = sigma_s (phi^{l+1/2} - phi^l),   phi^{l+1} = phi^{l+1/2} + δ,
// with the Marshak condition (homogeneous: the error has no incoming light) at empty cells and
// the domain boundary, and zero net current on specularly reflective domain faces (a mirror
// returns all that leaves: n·F = 0). A low mirror face returns the same sweep's light; a high
// one the previous sweep's (transport_sweep.h), so there the error's net inward current is the
// change dJ of the sweep's outgoing current (e_in = R(e_out + psi_out^new - psi_out^old)):
// correct() takes it as a boundary source, b += h dJ per boundary cell. Without it (GMRES's
// preconditioner) high mirror faces keep Marshak; zero current there without the source made
// DSA diverge. sigma_s = kappa* a*, and
//   D = 1/(3 kappa_tr) + h/4,   kappa_tr = kappa* (1 - a* chi*_1) = kappa (1 - a g).
// The h/4 is the step scheme's own numerical diffusion: upwinding adds |mu_a| h/2 ∂²_a psi per
// direction, and for nearly isotropic psi (1/4π) Σ_n w_n |mu_a,n| h/2 = h/4 per axis. In thick
// cells it dominates (the step scheme's diffusion limit) and with it the Marshak face flux
// 2D/(4D + h) phi_P tends to phi_P/4, exactly the step scheme's outflow of an isotropic cell;
// without it DSA diverged on the tau-100 cube (6.25 mean free paths per cell: change ~1.2 per
// iteration), with it the cube converges in the test's bound (tests/verification/dom).
//
// The same solve is the preconditioner of GMRES (gmres.h): solve() takes any fluence change r
// and returns δ = A^{-1} sigma_s r, the correction of the last call.
//
// Collective over d.comm(). The operator does not change between iterations (only the
// right-hand side does): the hypre grid, matrix and PFMG-PCG setup are built ONCE in the
// constructor and every correct() is one solve (about half of the wall time went into the
// per-iteration re-assembly and setup before).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "solvers/diffusion/assemble.h"
#include "solvers/diffusion/diffusion_problem.h"
#include "solvers/diffusion/hypre_struct.h"
#include "solvers/dom/band_problem.h"
#include "src/core/decomposition.h"
#include "src/core/report.h"
#include "src/model/options.h"

namespace nimbus::dom {

class DiffusionSynthetic {
public:
    // Collective. p must outlive this object. reflective: the sweep's mirror faces
    // (SweepBoundary::reflective, x-, x+, y-, y+, z-, z+); lagged_sources: correct() will get the
    // high mirror faces' current changes (else those faces keep Marshak).
    DiffusionSynthetic(const Decomposition& d, const BandProblem& p, double tolerance,
                       const std::array<bool, 6>& reflective = {}, bool lagged_sources = false);
    ~DiffusionSynthetic();
    DiffusionSynthetic(const DiffusionSynthetic&) = delete;
    DiffusionSynthetic& operator=(const DiffusionSynthetic&) = delete;
    // Collective. Adds δ to fluence (owned cells). Returns the linear solver's iterations (0
    // when the right-hand side vanishes everywhere). Throws Error (on every rank) when the
    // true relative residual stays above the tolerance.
    // mirror_source: dJ / h per boundary cell of the high mirror faces (TransportSweeper::
    // for_each_lagged_mirror_change), owned cells, or null.
    int correct(const Field<double>& fluence_old, Field<double>& fluence,
                const Field<double>* mirror_source = nullptr);
    // Collective. δ = A^{-1} sigma_s r for a fluence change r (W/m², owned cells, 1 component),
    // into last_correction(). Same return value and errors as correct(). A linear map of r up to
    // the solver tolerance (PCG from a zero initial guess).
    int solve(const Field<double>& r, const Field<double>* mirror_source = nullptr);
    // The correction of the last call (owned cells, W/m²).
    const Field<double>& last_correction() const { return delta_; }

private:
    const Decomposition& d_;
    const BandProblem& p_;
    diffusion::DiffusionProblem dp_;
    diffusion::SolveRegion region_;
    DiffusionOptions opt_;
    double kappa_floor_ = 0.0;
    Field<double> delta_;
    Field<double> change_;  // correct()'s fluence change, kept to avoid an allocation per call
    // The hypre system on d.local() ∩ region (set up once; null when the region is empty).
    Box box_;
    std::vector<char> full_;  // per cell of box_, x fastest
    std::unique_ptr<diffusion::hypre::Grid> grid_;
    std::unique_ptr<diffusion::hypre::SymmetricStencil7> stencil_;
    std::unique_ptr<diffusion::hypre::Matrix> A_;
    std::unique_ptr<diffusion::hypre::Vector> b_, x_, r_;
    std::unique_ptr<diffusion::hypre::Solver> solver_;
};

}  // namespace nimbus::dom
