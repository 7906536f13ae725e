// Halo exchange: the one way ghost layers are filled from neighbouring ranks.
#pragma once

#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus {

// Collective over d.comm(). Fills all ghost cells of f (faces, edges and corners) that lie
// inside the global domain (or wrap around a periodic axis) with the owners' values. Ghosts
// outside a non-periodic domain are left untouched (the caller's boundary condition).
// Axes are exchanged one after another over the grown box, which fills edges and corners.
// Throws Error on every rank when a split axis has a rank box thinner than the ghost depth.
void exchange_halo(Field<double>& f, const Decomposition& d);

}  // namespace nimbus
