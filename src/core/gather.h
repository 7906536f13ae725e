// Replication of a distributed field: every rank gets the whole global grid. For models that
// need random access to the full medium (Monte Carlo tracing, exact long characteristics);
// memory is global cells x 8 bytes on every rank, so callers check a budget first.
#pragma once

#include <vector>

#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus {

// Collective over d.comm(). Component 0 of f's owned cells of every rank, as a dense array
// [z][y][x] over d.global() (x fastest), on every rank.
std::vector<double> allgather_global(const Field<double>& f, const Decomposition& d);

}  // namespace nimbus
