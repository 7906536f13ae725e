// One diffusion system: coefficients on the rank's box and one or more right-hand sides that
// share the matrix (diffusion_kernel.h for the equation). Built by the model from the medium
// and the light pass (sources.h), or directly by tests (manufactured solutions).
//
// kappa_tr and sigma_a live on d.local() of the Decomposition the system is solved on; Q0, G and
// escape_flux on d.local() ∩ rhs_within (all of d.local() when rhs_within is empty). Ownership:
// plain values, the caller owns everything.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "src/core/box.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus::diffusion {

struct DiffusionProblem {
    double h = 1.0;                    // cell edge, metres
    Int3 n{0, 0, 0};                   // global cells per axis
    std::array<bool, 3> periodic{false, false, false};
    // Domain faces (x-, x+, y-, y+, z-, z+) that are mirrors: zero net flux through them
    // (DOM's DSA on specularly reflective faces) instead of the Marshak condition.
    std::array<bool, 6> reflective{};
    Field<double> kappa_tr;            // 1/m, owned + 1 ghost, halo-exchanged; 0 = empty cell
    Field<double> sigma_a;             // rho * sigma_a, 1/m, owned (ghosts unused)
    std::vector<Field<double>> Q0;     // per rhs: (1/4π)∫Q dw, owned
    std::vector<Field<double>> G;      // per rhs: Q1/kappa_tr, 3 components, owned + 1 ghost
    // Per rhs, or none: the part of the cells' sources that leaves through their Marshak faces
    // directly instead of entering Q0 (the first scatter in the sheet under a lit face of an
    // optically thick cell: diffusion_kernel.h, marshak_escape), as a flux per 4π per unit
    // face area, signed along each axis: Σ_faces s e_f h (3 components, owned). The face
    // fluxes carry it (Assembler::flux); Q0 holds only what stays.
    std::vector<Field<double>> escape_flux;
    // Where the right-hand sides' fields live (their owned box is d.local() ∩ rhs_within): a
    // global box holding every full cell, whole along periodic axes (make_problem: the full
    // cells' bounding box, the solve region without its margin), or empty for all of d.local()
    // (tests, dom's DSA). They are alive through the solve, at the model's peak memory: on the
    // default cloud (1 rank, 2 right-hand sides; the box is 36% of the grid) the run's peak went
    // from 225.7 to 195.8 MiB.
    Box rhs_within;
};

// exchange_halo of a right-hand side's G (p.G[r], or a copy on the same box).
void exchange_rhs_halo(const DiffusionProblem& p, Field<double>& G, const Decomposition& d);

// The solve region: bounding box of the full cells grown by `margin`, clipped to the domain;
// the whole axis where periodic. Empty when no cell is full.
struct SolveRegion {
    Box box;    // where the system is solved
    Box cloud;  // the full cells' bounding box (the whole axis where periodic)
    std::int64_t cells() const { return box.cells(); }
};

// The floor of kappa_tr in D and G (diffusion_kernel.h), 1/m: one for every cell, or one per
// piece of cloud (solve_region.h, transport_floor).
struct TransportFloor {
    double uniform = 0.0;           // the floor when `piece` is empty
    Field<std::int32_t> piece;      // owned cells of the solve region ∩ the rank's box: the cell's piece
    std::vector<double> per_piece;  // the floor of each piece
    double largest = 0.0;           // the floor in the piece with the most cells (the run report's)
    int pieces = -1;                // pieces of cloud (cloud_pieces.h); -1: not looked for

    // The floor at full cell (i, j, k) of this rank.
    double at(int i, int j, int k) const {
        return per_piece.empty() ? uniform : per_piece[static_cast<size_t>(piece(i, j, k))];
    }
};

// What the solve did, for the run report.
struct SolveStats {
    int iterations = 0;            // total over restarts
    int restarts = 0;              // extra rounds needed to push the TRUE residual below tol
    double reported_residual = 0;  // solver's own final relative residual
    double true_residual = 0;      // ||b - A x|| / ||b||, computed after the solve
    double assemble_seconds = 0, setup_seconds = 0, solve_seconds = 0;
    // Negative U of the P1 solution (global counts), before clamping: in cells with a Marshak
    // face (the boundary layer where P1 with a forward-peaked source fails) and elsewhere.
    std::int64_t negative_boundary_cells = 0, negative_interior_cells = 0;
    double min_U = 0.0, min_U_interior = 0.0;  // most negative U (all cells / no Marshak face)
    double max_U = 0.0;                         // largest U, the scale of the minima
};

struct DiffusionResult {
    std::vector<Field<double>> U;     // per rhs, owned + 1 ghost (halo-exchanged), 0 in empty cells
    std::vector<Field<double>> flux;  // per rhs, F = 4π (G - D∇U), 3 components, owned + 1 ghost
    SolveRegion region;
    TransportFloor kappa_floor;       // the transport cap's floor per cell (solve_region.h)
    std::vector<SolveStats> stats;    // per rhs
};

}  // namespace nimbus::diffusion
