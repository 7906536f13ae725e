// Empty-space distance for the grid walk (grid_walk.h): for every cell, the chessboard
// distance to the nearest cell with kappa > 0, where the layer just outside the grid counts
// as non-empty (so a skipped cube never leaves the grid). 0 for non-empty cells, capped at
// 255. Exact two-pass chamfer transform with the 26-neighbour unit mask (Rosenfeld & Pfaltz
// 1966), on a copy padded with one non-empty layer so the inner loops need no bounds checks.
// Not collective; allocates the result.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "src/core/grid_walk.h"

namespace nimbus {

std::vector<std::uint8_t> empty_space_distance(const std::array<int, 3>& n, const std::vector<float>& kappa);

// The walk's interleaved grid: kappa (1/cell) and its empty-space distance per cell, x fastest,
// padded with the ghost layer of grid_walk.h (kappa 0, skip outside_skip). The grid is the
// whole domain (origin 0, domain n) unless the caller sets origin and domain.
VoxelGrid make_voxels(const std::array<int, 3>& n, const std::vector<float>& kappa);

}  // namespace nimbus
