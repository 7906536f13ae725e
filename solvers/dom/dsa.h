// Diffusion synthetic acceleration (Alcouffe 1977; Adams & Larsen 2002 §4) on the diffusion
// model's cell-centred hypre assembly (solvers/diffusion: Assembler, solve_with_hypre), with the
// first moment corrected too (P1 synthetic acceleration).
// A transport sweep has produced the fluence phi^{l+1/2} and flux F^{l+1/2} from phi^l, F^l; the
// changes R0 = phi^{l+1/2} - phi^l and R1 = F^{l+1/2} - F^l are the scattering source the error
// misses. Its P1 moments (zeroth and first moment of the transport equation for the error, HG
// first moment chi_1) are
//   ∇·δF + sigma_a δ = sigma_s R0,     δF = (chi_1 sigma_s R1 - ∇δ/3) / kappa_tr,
// i.e. the diffusion problem with a divergence source (the assembly's G = Q1/kappa_tr):
//   -∇·(D ∇δ) + sigma_a δ = sigma_s R0 - ∇·G,   G = chi_1 sigma_s R1 / kappa_tr,
//   phi^{l+1} = phi^{l+1/2} + δ,   F^{l+1} = F^{l+1/2} + G - D ∇δ,
// with the Marshak condition (homogeneous: the error has no incoming light) at empty cells and
// the domain boundary, and zero net current on specularly reflective domain faces (a mirror
// returns all that leaves: n·F = 0). Correcting only the isotropic part (G = 0, F unchanged),
// as plain DSA does, leaves the first moment to source iteration, whose error decays like
// a chi_1 per sweep and flips sign for chi_1 < 0. But the P1 current equation has no damping of
// the current's source at short wavelengths (the l = 2 moment that would give it is dropped): a
// transverse current error that the sweep's streaming has already removed is put back, times
// chi_1 sigma_s / kappa_tr (2.0 at g = 0.85, P3 delta-M), and the iteration diverged on the
// dense cube. So G is FILTERED first, G <- (kappa_tr - ∇·nu∇)^{-1} kappa_tr G with
// nu = 0.2 / kappa* (a fifth of a mean free path; one PFMG cycle per component, Marshak at the
// medium's faces): long
// waves, where P1 holds, keep their current correction, waves shorter than a mean free path lose
// it. Spectral radius in a Fourier analysis of the infinite medium (jobs/dsa_fourier.py: albedo
// 0.99, S16 x 32 product quadrature, delta-M P3): g = 0.85 plain DSA 0.72, with G 2.03, with G
// filtered 0.47; g = -0.5: 1.11 (divergent), 0.35, 0.33; g = -0.9: 1.76, 0.80, 0.80.
// A low mirror face returns the same sweep's light; a high
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
// iteration), with it the cube converges in the test's bound (tests/verification/dom). It is
// numerical diffusion of the streaming term, not of the collisions: G keeps the physical
// kappa_tr.
//
// The same solve is the preconditioner of GMRES (gmres.h): solve() takes any fluence and flux
// change (R0, R1) and returns δ and δF, the corrections of the last call.
//
// Each correction's diffusion system is solved by kVCycles PFMG V-cycles from zero: a fixed
// linear map, as GMRES's preconditioner needs and source iteration does not mind (a correction
// only has to catch the sweep's slow error modes; its own error is swept and corrected again in
// the next iteration). Against PFMG-PCG to a relative residual of 0.1 (source iteration's until
// the thirty-second session), two cycles took the same outer iterations on every scene and hard
// case measured (solvers/dom/README.md, "DSA's linear solve") for 0.78x the DSA time: no
// preconditioned-residual bookkeeping and no true-residual product per correction.
//
// Collective over d.comm(). The operator does not change between iterations (only the
// right-hand side does): the hypre grid, matrix and PFMG setup are built ONCE in the
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
    // PFMG V-cycles from zero per correction (above). One cycle took one more outer iteration
    // on 4 of the 10 cases and moved the answers up to 3e-5 (rel L2; two cycles: 4e-6).
    static constexpr int kVCycles = 2;
    // Collective. p must outlive this object. reflective: the sweep's mirror faces
    // (SweepBoundary::reflective, x-, x+, y-, y+, z-, z+); lagged_sources: correct() will get the
    // high mirror faces' current changes (else those faces keep Marshak).
    DiffusionSynthetic(const Decomposition& d, const BandProblem& p, const std::array<bool, 6>& reflective = {},
                       bool lagged_sources = false);
    ~DiffusionSynthetic();
    DiffusionSynthetic(const DiffusionSynthetic&) = delete;
    DiffusionSynthetic& operator=(const DiffusionSynthetic&) = delete;
    // Collective. Adds δ to fluence and δF to flux (owned cells) for the sweep's changes
    // R0 = fluence - fluence_old, R1 = flux - flux_old; with_current false: the isotropic
    // correction alone (δF = 0, the cost of plain DSA). Returns the V-cycles run (kVCycles, or 0
    // when the right-hand side vanishes everywhere). Throws Error (on every rank) when the
    // right-hand side is not finite.
    // mirror_source: dJ / h per boundary cell of the high mirror faces (TransportSweeper::
    // for_each_lagged_mirror_change), owned cells, or null.
    int correct(const Field<double>& fluence_old, const Field<double>& flux_old, Field<double>& fluence,
                Field<double>& flux, bool with_current, const Field<double>* mirror_source = nullptr);
    // Collective. δ and δF for a fluence change r0 (W/m², owned cells, 1 component) and a flux
    // change r1 (3 components, or null: the isotropic correction alone, δF = 0), into last_correction() and
    // last_current_correction(). Same return value and errors as correct(). Exactly a linear map
    // of (r0, r1): fixed V-cycles from a zero initial guess.
    int solve(const Field<double>& r0, const Field<double>* r1, const Field<double>* mirror_source = nullptr);
    // The corrections of the last call (owned cells, W/m²): δ, and δF (3 components; zero without
    // r1 or when the phase function has no first moment, chi_1 = 0, which the sweep would not read).
    const Field<double>& last_correction() const { return delta_; }
    const Field<double>& last_current_correction() const { return current_; }
    // The owned cells where the corrections can be nonzero (d.local() ∩ the solve region, the
    // non-empty cells' bounding box plus a margin); they are zero everywhere else.
    const Box& box() const { return box_; }

private:
    void solve_system(std::vector<double>& b, std::vector<double>& x);  // collective (b: hypre takes it non-const)
    void set_up_current_filter();                    // collective
    void filter_current_source(Field<double>& G);     // collective
    // The current's source is filtered (above) with width nu = kCurrentFilterWidth / kappa*.
    static constexpr double kCurrentFilterWidth = 0.2;
    const Decomposition& d_;
    const BandProblem& p_;
    diffusion::DiffusionProblem dp_;
    diffusion::SolveRegion region_;
    diffusion::TransportFloor kappa_floor_;  // the diffusion model's transport cap, per piece of cloud
    double chi1_ = 0.0;      // the first Legendre moment of the (scaled) phase function
    Field<double> delta_;
    Field<double> delta_halo_;  // δ with its ghost layer, for the current's face differences
    Field<double> current_;  // δF, 3 components
    Field<double> change_, flux_change_;  // correct()'s R0 and R1, kept to avoid allocations per call
    std::unique_ptr<diffusion::Assembler> assembler_;
    // The hypre system on d.local() ∩ region (set up once; null when the region is empty).
    Box box_;
    std::vector<char> full_;  // per cell of box_, x fastest
    std::unique_ptr<diffusion::hypre::Grid> grid_;
    std::unique_ptr<diffusion::hypre::SymmetricStencil7> stencil_;
    std::unique_ptr<diffusion::hypre::Matrix> A_;
    std::unique_ptr<diffusion::hypre::Vector> b_, x_;
    std::unique_ptr<diffusion::hypre::Solver> solver_;
    Int3 period_{0, 0, 0};            // the hypre grid's periods
    diffusion::DiffusionProblem fp_;  // the current filter's problem (set up at its first use)
    std::unique_ptr<diffusion::hypre::Matrix> filter_A_;
    std::unique_ptr<diffusion::hypre::Solver> filter_;
};

}  // namespace nimbus::dom
