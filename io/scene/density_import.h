// Density from files: an HDF5 dataset of shape [nz][ny][nx] (any floating-point or integer
// type, converted to double by HDF5), or a raw file of nx*ny*nz little-endian float32 values,
// x fastest. Each rank reads only its own box.
// load_medium builds a scene's whole Medium from whichever density source it names.
#pragma once

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/scene/medium.h"
#include "src/scene/scene.h"

namespace nimbus {

// Collective over d.comm(). Fills rho (owned box + ghosts, ghosts exchanged; ghosts outside
// the domain 0), scaled by spec.density. Throws Error on every rank for a missing file, a
// missing dataset, or a wrong size (the message gives expected and found sizes).
void read_density(const MediumSpec& spec, const Decomposition& d, Field<double>& rho);

// The scene's medium on d: its grid, its bands and the density on the rank's box + 1 ghost layer
// (procedural, or read_density for an hdf5/raw medium), checked by check_density (finite, >= 0).
// A rank that cannot allocate its box makes every rank throw the same Error ("not enough memory").
// Collective over d.comm(); throws the same Error on every rank.
Medium load_medium(const Scene& scene, const Decomposition& d);

}  // namespace nimbus
