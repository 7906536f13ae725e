// Moving a distributed array between two decompositions of the same grid over the same ranks
// (e.g. the field's slabs and the exact light pass's work-balanced slabs,
// solvers/light/light_slabs.h): every rank sends the part of its box that another rank's new
// box covers. One MPI_Alltoallv; counts beyond 2^31 go in blocks (mpi_counts.h).
#pragma once

#include <span>
#include <vector>

#include "src/core/decomposition.h"

namespace nimbus {

// Collective over from.comm(); `to` must number the same ranks alike (to = from.with_cuts(...),
// or another Decomposition of the same communicator: nimbus never reorders ranks). values: this rank's cells of from.local(), x fastest; returns
// its cells of to.local(), x fastest.
std::vector<double> move_cells(const Decomposition& from, std::span<const double> values, const Decomposition& to);

}  // namespace nimbus
