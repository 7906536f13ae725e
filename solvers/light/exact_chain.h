// Exact light pass pipelined down the slab chain (long characteristics without replication).
// Every cell centre's ray back toward the light is integrated exactly through the piecewise-
// constant cells. The ray from a cell crosses the slabs of the ranks upstream of it; each rank
// integrates, for every ray that crosses its slab, the piece inside its own slab (only its own
// density is needed), and the partial sums travel down the chain one rank's worth of rays at a
// time: rank r receives from its upstream neighbour the partial sums of the rays of rank q (q =
// r, then each rank further downstream), adds its own piece, keeps the result if q = r and
// passes it on otherwise. The tracing has no dependency on other ranks, so it all overlaps; only
// the additions wait. Work: a rank traces every ray that crosses its slab, so ranks nearer the
// light trace more (the price of not replicating the density).
#pragma once

#include <array>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/vec3.h"
#include "src/physics/lights.h"

namespace nimbus {

// ∫ rho ds (in cell units: multiply by h) along the ray from pos (global cell coordinates) in
// unit direction b, through the cells of rho's owned slab [z0, z1), until it leaves that z range
// or, on a non-periodic axis, the domain's x/y range (periodic x/y wrap). Pure.
double slab_ray_integral(const Field<double>& rho, const Int3& n, const std::array<bool, 3>& periodic,
                         const Vec3& b, std::array<double, 3> pos);

// Collective over d.comm(); slabs along z. tau_rho (owned box, ghosts untouched) of one light.
void exact_tau_chain(const Decomposition& d, const Field<double>& rho, double h, const DirectionalLight& light,
                     Field<double>& tau);

}  // namespace nimbus
