// The pieces of a cloud: the sets of full cells (kappa_tr > 0) joined through their faces, across
// rank boundaries and periodic faces. An empty cell couples nothing in the P1 system (its
// faces are Marshak faces), so the matrix is block diagonal over the pieces and each piece is a
// problem of its own. Its transport-length cap (diffusion_kernel.h) is therefore taken from its
// own size (solve_region.h, transport_floor), so that another cloud elsewhere, or one speck of
// density in a far corner, does not change a cloud's answer.
#pragma once

#include <cstdint>
#include <vector>

#include "src/core/box.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus::diffusion {

struct CloudPieces {
    // Owned cells of `box` (the region ∩ the rank's box): the piece's index, -1 in empty cells.
    Field<std::int32_t> index;
    // Per piece, the same on every rank, ordered by the piece's lowest global cell (x fastest):
    std::vector<Box> bounds;           // bounding box of its cells, whole along periodic axes
    std::vector<std::int64_t> cells;   // number of its cells
};

// Collective over d.comm(). kappa_tr: owned cells of d.local() (ghosts not read); region: a box
// that holds every full cell and is whole along the periodic axes (SolveRegion::box). The same
// pieces, in the same order, on any number of ranks.
CloudPieces find_cloud_pieces(const Decomposition& d, const Field<double>& kappa_tr, const Box& region);

}  // namespace nimbus::diffusion
