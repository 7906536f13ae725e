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

// The same for a field on a part of the rank's box: f.owned() == d.local().intersect(within) for
// a global box `within` (whole along periodic axes), one ghost layer. Ghosts are filled from the
// adjacent ranks' parts, and where `within` wraps a periodic axis; ghosts outside `within` are
// left untouched. A rank whose part is empty exchanges nothing, and neither do its neighbours
// with it. Collective over d.comm().
void exchange_halo(Field<double>& f, const Decomposition& d, const Box& within);

// The reverse of exchange_halo along one axis, for fields that receive deposits in their ghost
// cells (LPM's maps): each ghost layer of f (one deep) is added into the adjacent rank's boundary
// layer of owned cells, over the allocated extent of the other axes, then every ghost cell of f
// is zeroed (deposits beyond the domain along `axis`, and along other axes, are dropped).
// Collective over d.comm().
void accumulate_halo(Field<double>& f, const Decomposition& d, int axis);

}  // namespace nimbus
