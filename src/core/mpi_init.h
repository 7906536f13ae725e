// MPI start-up for every nimbus executable (the CLI, the test main, the benchmarks): the
// process-level MPI settings nimbus depends on, applied before MPI_Init, then MPI_Init.
//
// Open MPI 4.1 (Debian 12 ships 4.1.4) writes collective MPI-IO through ompio, whose default
// collective-write component fcoll/vulcan can put wrong values in the file when ranks write
// interleaved pieces of it (open-mpi/ompi#12718, fixed upstream in 2024). nimbus's parallel
// HDF5 output is exactly that case: with the grid split along x on 3 ranks, 4 to 7 of 10-15
// runs of test_io_output's round trip wrote wrong cells on a loaded 2-core machine, none with
// fcoll dynamic_gen2, individual, two_phase or dynamic, or with ROMIO. So, with Open MPI,
// unless the user chose the MPI-IO layer (OMPI_MCA_io or OMPI_MCA_fcoll in the environment,
// which is also where `mpiexec --mca fcoll X` puts it), nimbus selects fcoll dynamic_gen2.
#pragma once

#include <string>

namespace nimbus {

// The fcoll component nimbus selects (Open MPI only) when the user did not choose one.
inline constexpr const char* kDefaultFcoll = "dynamic_gen2";

// Applies the settings above (Open MPI only; never overrides the user's) and calls MPI_Init.
void init_mpi(int* argc, char*** argv);

// What init_mpi decided about MPI-IO, for the run report and the tests: "fcoll=dynamic_gen2
// (nimbus default)", "fcoll=X (user)", "io=X (user)", or "" when the MPI is not Open MPI.
const std::string& mpi_io_choice();

}  // namespace nimbus
