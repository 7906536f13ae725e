// Density from files: an HDF5 dataset of shape [nz][ny][nx] (any floating type), or a raw file
// of nx*ny*nz little-endian float32 values, x fastest. Each rank reads only its own box.
#pragma once

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/scene/scene.h"

namespace nimbus {

// Collective over d.comm(). Fills rho (owned box + ghosts, ghosts exchanged; ghosts outside
// the domain 0), scaled by spec.density. Throws Error on every rank for a missing file, a
// missing dataset, or a wrong size (the message gives expected and found sizes).
void read_density(const MediumSpec& spec, const Decomposition& d, Field<double>& rho);

}  // namespace nimbus
