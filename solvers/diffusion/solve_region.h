// The region the diffusion system is solved on: the bounding box of the full cells
// (kappa_tr > 0) grown by `margin` cells and clipped to the domain; the whole axis along a
// periodic axis. Cells outside are empty and carry no diffuse light in this model, so the
// answer is the same as on the whole domain (the Marshak faces of the cloud do not change), and
// the same for every margin: the default transport-length cap is taken from the cloud's own
// bounding box, not from the grown region (test SolveRegionIsTheBoundingBoxPlusMargin).
#pragma once

#include "solvers/diffusion/diffusion_problem.h"
#include "src/core/decomposition.h"

namespace nimbus::diffusion {

// Collective over d.comm() (one MPI_Allreduce, bounding_box). Empty box when no cell is full anywhere.
SolveRegion find_solve_region(const Decomposition& d, const DiffusionProblem& p, int margin);

// Default cap on the transport mean free path (m): half the smallest extent of the full cells'
// bounding box (r.cloud) over the non-periodic axes, the largest distance from a point of that
// box to its boundary (diffusion_kernel.h); +inf (no cap) when every axis is periodic.
double default_transport_length(const SolveRegion& r, const DiffusionProblem& p);

}  // namespace nimbus::diffusion
