#include "src/core/mpi_init.h"

#include <mpi.h>

#include <cstdlib>

namespace nimbus {

namespace {
std::string g_choice;
}

void init_mpi(int* argc, char*** argv) {
#ifdef OPEN_MPI
    // Open MPI reads OMPI_MCA_* from the environment when its frameworks open, inside MPI_Init.
    if (const char* io = std::getenv("OMPI_MCA_io"); io != nullptr && *io != '\0') {
        g_choice = std::string("io=") + io + " (user)";
    } else if (const char* fcoll = std::getenv("OMPI_MCA_fcoll"); fcoll != nullptr && *fcoll != '\0') {
        g_choice = std::string("fcoll=") + fcoll + " (user)";
    } else {
        setenv("OMPI_MCA_fcoll", kDefaultFcoll, 1);
        g_choice = std::string("fcoll=") + kDefaultFcoll + " (nimbus default)";
    }
#endif
    MPI_Init(argc, argv);
}

const std::string& mpi_io_choice() { return g_choice; }

}  // namespace nimbus
