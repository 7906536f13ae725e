// The view-depth prepass of the distributed ray caster (for a view-path source, view_source.h):
// a rank marches only its piece of each view ray, so the view depths (tau_view, s_view) at its
// piece's entry come from the ranks in front. Every rank sums its pieces' depths (march_depth);
// the sums go to the owner of the pixel's image row, which orders a pixel's pieces by their sort
// key (first step on the ray's lattice = visibility order) and returns the EXCLUSIVE prefix sum:
//   depth_entry(piece) = Σ_{pieces of the same pixel with a smaller key} depth(piece').
#pragma once

#include <mpi.h>

#include <array>
#include <cstdint>
#include <vector>

namespace nimbus {

struct PieceDepth {
    std::int32_t pixel = 0;  // row-major pixel index
    std::int32_t key = 0;    // first step of the piece on the ray's lattice
    double tau = 0.0, s = 0.0;  // the piece's own depth sums
};

// Collective over comm. Returns, in the order of `pieces`, the depths {tau, s} at each piece's
// entry. height: image rows (the row split matches composite_image's).
std::vector<std::array<double, 2>> view_depth_at_entry(const std::vector<PieceDepth>& pieces,
                                                       int width, int height, MPI_Comm comm);

}  // namespace nimbus
