// One HDF5 file per run, written collectively with parallel HDF5 (MPI-IO), plus an XDMF
// sidecar so ParaView opens it. Both are written under temporary names and made final with
// the run's other outputs by OutputFiles::commit() (io/output/output_files.h): a failed run
// never leaves a half-written file under the final name.
//
// Layout (documented in README "Outputs"):
//   /fields/<name>            band-free scalar fields, e.g. density: float32 [nz][ny][nx]
//   /fields/<name>/<band>     per-band fields, e.g. fluence_diffuse/r: float32 [nz][ny][nx]
//   /fields/<name>/<band>     per-band vectors, e.g. flux_diffuse/r: float32 [nz][ny][nx][3]
//   every field dataset has string attributes "units" and "description"
//   /scene (string attribute "toml": the effective scene), /run (attribute "report": JSON)
//
// Errors, including a full disk, are collective: every rank throws the same Error and the
// file is closed on all ranks together (see the life cycle in hdf5_writer.cpp).
#pragma once

#include <mpi.h>

#include <memory>
#include <string>

#include "io/output/output_files.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/grid.h"

namespace nimbus {

class Hdf5Writer {
public:
    // Collective. Creates the temporary of path, registered with files (not owned; it must
    // outlive the writer) together with the XDMF sidecar's; throws Error on every rank if it
    // cannot (e.g. the folder does not exist or is not writable).
    Hdf5Writer(const Decomposition& d, const Grid& grid, std::string path, OutputFiles& files);
    // A writer with a set of its own, for a file written alone: commit() makes it final.
    Hdf5Writer(const Decomposition& d, const Grid& grid, std::string path);
    // Not closed (an Error unwinds the run): closes the file on every rank (collective by
    // nature: every rank destroys its writer through the same code). The temporaries are
    // removed by the OutputFiles set.
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
    // Collective: closes the file and writes the XDMF sidecar, both still under their
    // temporary names; the set's commit() makes them final.
    void close();
    // Collective, only for a writer with a set of its own: close(), then commit the set.
    void commit();
    const std::string& path() const { return path_; }
    const std::string& temporary_path() const;

private:
    struct Impl;
    void open(const Decomposition& d, const Grid& grid, OutputFiles& files);

    std::unique_ptr<OutputFiles> own_files_;  // the set of a writer that commits alone
    std::unique_ptr<Impl> impl_;  // Impl is complete in the .cpp, where the destructor is
    std::string path_;
};

}  // namespace nimbus
