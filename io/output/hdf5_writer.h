// One HDF5 file per run, written collectively with parallel HDF5 (MPI-IO), plus an XDMF
// sidecar so ParaView opens it. The file is written as "<path>.tmp" and renamed to <path>
// only by commit(): a failed run never leaves a half-written file under the final name.
//
// Layout (documented in README "Outputs"):
//   /fields/<name>            band-free scalar fields, e.g. density: float32 [nz][ny][nx]
//   /fields/<name>/<band>     per-band fields, e.g. fluence_diffuse/r: float32 [nz][ny][nx]
//   /fields/<name>/<band>     per-band vectors, e.g. flux_diffuse/r: float32 [nz][ny][nx][3]
//   every field dataset has string attributes "units" and "description"
//   /scene (string attribute "toml": the effective scene), /run (attribute "report": JSON)
#pragma once

#include <mpi.h>

#include <string>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/grid.h"

namespace nimbus {

class Hdf5Writer {
public:
    // Collective. Creates <path>.tmp; throws Error on every rank if it cannot (e.g. the folder
    // does not exist or is not writable).
    Hdf5Writer(const Decomposition& d, const Grid& grid, std::string path);
    // Not committed: closes and removes the temporary file (collective by nature: every rank
    // destroys its writer on the same path through the same code).
    ~Hdf5Writer();
    Hdf5Writer(const Hdf5Writer&) = delete;
    Hdf5Writer& operator=(const Hdf5Writer&) = delete;

    // Collective. name is a path below /fields, e.g. "density" or "fluence_diffuse/r".
    // f has ncomp 1 (scalar) or 3 (vector); only its owned box is written.
    void write_field(const std::string& name, const Field<double>& f, const std::string& units,
                     const std::string& description);
    // Collective. A string attribute on a group ("/scene", "/run"), created if needed.
    void write_string_attribute(const std::string& group, const std::string& key,
                                const std::string& value);
    // Collective: closes the file, renames it to the final path, writes <stem>.xdmf beside it.
    void commit();
    const std::string& path() const { return path_; }

private:
    struct Impl;
    Impl* impl_;
    std::string path_;
};

}  // namespace nimbus
