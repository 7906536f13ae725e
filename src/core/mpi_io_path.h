// The longest file path nimbus hands to MPI-IO. Open MPI's MPI-IO (its shared-file-pointer
// components, queried by every MPI_File_open, also under parallel HDF5) overflows a fixed buffer
// on file paths of about 245 characters and aborts the run with "buffer overflow detected"
// (Debian 12's Open MPI 4.1; QA findings: exit 134 for a long output path and for a long
// medium.file). Paths up to 230 characters were measured to work.
#pragma once

#include <cstddef>

namespace nimbus {

inline constexpr std::size_t kMaxMpiIoPath = 230;

}  // namespace nimbus
