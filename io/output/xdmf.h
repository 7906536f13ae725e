// XDMF 2 sidecar for a nimbus HDF5 output, so ParaView/VisIt open the fields directly.
// Pure text generation, no MPI, no HDF5. The grid is a 3DCoRectMesh with (nz+1, ny+1, nx+1)
// nodes and ORIGIN_DXDYDZ geometry (XDMF orders both triples z, y, x); every field is a
// cell-centred Attribute whose DataItem points at "<h5 file name>:/fields/<name>", a name
// relative to the sidecar's folder so the pair can be moved together.
#pragma once

#include <string>
#include <vector>

#include "src/core/grid.h"

namespace nimbus {

struct XdmfField {
    std::string name;  // path below /fields, e.g. "fluence_diffuse/r"
    int ncomp = 1;     // 1 (Scalar) or 3 (Vector)
};

// The XDMF document. h5_file_name: the HDF5 file name as seen from the sidecar's folder.
std::string xdmf_document(const Grid& grid, const std::string& h5_file_name,
                          const std::vector<XdmfField>& fields);

// "<dir>/<stem>.xdmf" for an HDF5 path "<dir>/<stem>.h5".
std::string xdmf_path_for(const std::string& h5_path);

}  // namespace nimbus
