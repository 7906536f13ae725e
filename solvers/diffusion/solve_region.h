// The region the diffusion system is solved on: the bounding box of the full cells
// (kappa_tr > 0) grown by `margin` cells and clipped to the domain; the whole axis along a
// periodic axis. Cells outside are empty and carry no diffuse light in this model, so the
// answer is the same as on the whole domain (the Marshak faces of the cloud do not change), and
// the same for every margin: the default transport-length cap is taken from the bounding box of
// each piece of cloud, not from the grown region (test SolveRegionIsTheBoundingBoxPlusMargin).
#pragma once

#include "solvers/diffusion/diffusion_problem.h"
#include "src/core/decomposition.h"

namespace nimbus::diffusion {

// Collective over d.comm() (one MPI_Allreduce, bounding_box). Empty box when no cell is full anywhere.
SolveRegion find_solve_region(const Decomposition& d, const DiffusionProblem& p, int margin);

// Cap on the transport mean free path (m) of a piece of cloud whose full cells have the bounding
// box `cloud`: half its smallest extent over the non-periodic axes, the largest distance from a
// point of that box to its boundary (diffusion_kernel.h); +inf (no cap) when every axis is
// periodic.
double default_transport_length(const Box& cloud, const DiffusionProblem& p);

// Collective over d.comm() unless max_transport_length > 0: then the floor is
// 1 / max_transport_length in every cell. Otherwise each piece of cloud (cloud_pieces.h) gets
// 1 / default_transport_length of its own bounding box, so that the answer in one piece does not
// depend on the others (1/+inf = 0: no cap when every axis is periodic).
TransportFloor transport_floor(const Decomposition& d, const DiffusionProblem& p, const SolveRegion& r,
                               double max_transport_length);

}  // namespace nimbus::diffusion
