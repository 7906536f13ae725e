// Memory a run needs per rank, estimated from the scene and the decomposition before anything
// is allocated (`nimbus info` reports it; `nimbus info` and `nimbus run` refuse a grid that
// would not fit, instead of failing in an allocation on some ranks).
#pragma once

#include <mpi.h>

#include <string>

#include "src/core/decomposition.h"
#include "src/scene/scene.h"

namespace nimbus::cmd {

struct MemoryEstimate {
    double bytes = 0;  // on this rank
    std::string what;  // what the figure covers, e.g. "light pass, render, model dom 677 MiB"
    bool replicated = false;  // the model copies the whole grid to every rank (Monte Carlo)
    double image_bytes = 0;   // the image's share of `bytes` (every rank holds rank 0's share)
    int image_width = 0, image_height = 0;  // camera.resolution
};

// Fields every run holds on this rank's box (+1 ghost layer): rho, tau_rho per light term,
// fluence per band (+ output copies), the renderer's view volume, the image fragments; plus
// the model's own share (ScatteringModel::memory_bytes: Monte Carlo's replicated grid, hypre's
// matrix and hierarchy, DOM's angular state and GMRES basis, LPM's coarse bins, the PSF
// pyramids), calibrated against measured peaks (docs in each model's memory_bytes). Not
// collective.
MemoryEstimate estimate_memory(const Scene& s, const Decomposition& d);

// Collective over comm. Throws Error on every rank when the ranks sharing a node would need
// together more than the node has available (MemAvailable, capped by a cgroup v2 limit); does
// nothing where that is unknown.
void check_memory_fits(MPI_Comm comm, const MemoryEstimate& m);

}  // namespace nimbus::cmd
