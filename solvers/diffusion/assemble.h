// Assembly of the 7-point cell-centred finite-volume rows of one DiffusionProblem
// (equation and face rules in diffusion_kernel.h). Not collective: reads the rank's fields
// (owned + the 1-ghost layer that the caller halo-exchanged) and answers per cell.
// The solver drivers (hypre, PETSc) copy rows into their own storage.
#pragma once

#include <array>
#include <span>

#include "solvers/diffusion/diffusion_kernel.h"
#include "solvers/diffusion/diffusion_problem.h"
#include "src/core/vec3.h"

namespace nimbus::diffusion {

// Stencil entry order used everywhere in this folder.
enum Entry { kXm = 0, kXp, kYm, kYp, kZm, kZp };

// A matrix row: A(P,P) = diag, A(P, P ± e_axis) = -coupling[entry]. Empty cells: diag 1.
struct CellRow {
    double diag = 1.0;
    std::array<double, 6> coupling{};
};

class Assembler {
public:
    // p must outlive the Assembler. kappa_floor (1/m): lower bound of kappa_tr in D, the same in
    // every cell.
    explicit Assembler(const DiffusionProblem& p, double kappa_floor = 0.0)
        : p_(p), kappa_floor_(kappa_floor) {}
    // The floor per piece of cloud (solve_region.h, transport_floor), read in the full cells of
    // this rank; it must outlive the Assembler. A face joins two cells of one piece, so both
    // sides have the same floor.
    Assembler(const DiffusionProblem& p, const TransportFloor& kappa_floor) : p_(p), floor_per_piece_(&kappa_floor) {}

    bool full(int i, int j, int k) const { return p_.kappa_tr(i, j, k) > 0.0; }
    CellRow row(int i, int j, int k) const;
    // The row and, in b[r], right-hand side r for r < b.size(), from one look at the cell's faces
    // (what the solver drivers assemble: on the bench cumulus at 64³ the row and rhs passes
    // looked up every face twice).
    CellRow row(int i, int j, int k, std::span<double> b) const;
    // Whether full cell (i, j, k) has a Marshak face (to an empty cell or the domain boundary);
    // false for an empty cell.
    bool has_marshak_face(int i, int j, int k) const;
    // Right-hand side r (index into p.Q0/p.G) at cell (i, j, k); 0 in empty cells.
    double rhs(int r, int i, int j, int k) const;
    // F = 4π (G - D∇U) at the cell centre: mean of the two face fluxes per axis, with the
    // source that leaves a face directly (p.escape_flux). U must have its ghost layer
    // exchanged. Zero in empty cells.
    Vec3 flux(int r, const Field<double>& U, int i, int j, int k) const;

private:
    // The floor of full cell (i, j, k) of this rank.
    double floor_at(int i, int j, int k) const {
        return floor_per_piece_ ? floor_per_piece_->at(i, j, k) : kappa_floor_;
    }
    // G consistent with the capped kappa_tr: Q1 / max(kappa_tr, floor) for a cell of kappa_tr kt
    // whose G component is g, floor that of the cell's piece.
    static double G_eff(double g, double kt, double floor) { return kt >= floor ? g : g * kt / floor; }
    // The six faces of a full cell, in Entry order (face e: axis e / 2, side -1 for even e), as
    // row, rhs and flux read them: what lies across (in, without G_n), the face's coefficient
    // (face_coefficient), and skip = a periodic axis of length 1 (the face couples the cell to
    // itself and carries nothing). Neighbours are read at the cell's index ± the field's stride
    // (the ghost layer holds the periodic images): on the bench cumulus at 64³ the index
    // arithmetic of (i, j, k) per face, twice per face, made the rows 150 ns per full cell (now 95).
    struct CellFaces {
        double kt = 0.0;     // the cell's kappa_tr
        double floor = 0.0;  // its piece's floor (a face joins two cells of one piece)
        std::array<FaceInput, 6> in;
        std::array<double, 6> coef{};
        std::array<bool, 6> skip{};
    };
    CellFaces faces(int i, int j, int k) const;
    // Face e of f with the neighbour's G_n (0 across an empty cell), g pointing at the cell's
    // components in G.
    static FaceInput with_neighbor_G(const Field<double>& G, const double* g, const CellFaces& f, int e) {
        FaceInput in = f.in[static_cast<size_t>(e)];
        const int axis = e / 2, s = e % 2 == 0 ? -1 : 1;
        if (in.neighbor_full) in.G_n = G_eff(g[s * G.stride(axis) + axis], in.kappa_tr_n, f.floor);
        return in;
    }
    // Right-hand side r of the cell whose faces are f.
    double rhs(int r, int i, int j, int k, const CellFaces& f) const;
    const DiffusionProblem& p_;
    double kappa_floor_ = 0.0;
    const TransportFloor* floor_per_piece_ = nullptr;
};

}  // namespace nimbus::diffusion
