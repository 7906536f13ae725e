# Finds the Debian-packaged stack (see jobs/install_deps.sh for the exact package list).
find_package(MPI REQUIRED COMPONENTS C CXX)

# hypre ships neither a CMake config nor a pkg-config file: import it by hand.
find_path(HYPRE_INCLUDE_DIR HYPRE_struct_ls.h PATH_SUFFIXES hypre REQUIRED)
find_library(HYPRE_LIBRARY NAMES HYPRE REQUIRED)
add_library(nimbus::hypre UNKNOWN IMPORTED)
set_target_properties(nimbus::hypre PROPERTIES
  IMPORTED_LOCATION "${HYPRE_LIBRARY}"
  INTERFACE_INCLUDE_DIRECTORIES "${HYPRE_INCLUDE_DIR}"
  INTERFACE_LINK_LIBRARIES MPI::MPI_C)

find_package(PkgConfig REQUIRED)
pkg_check_modules(PETSC REQUIRED IMPORTED_TARGET PETSc)

set(HDF5_PREFER_PARALLEL TRUE)
find_package(HDF5 REQUIRED COMPONENTS C)
if(NOT HDF5_IS_PARALLEL)
  message(FATAL_ERROR "nimbus needs a parallel HDF5 (Debian: libhdf5-openmpi-dev)")
endif()

find_package(OpenEXR 3 CONFIG REQUIRED)
find_package(PNG REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
find_package(toml11 CONFIG REQUIRED)
find_package(fmt CONFIG REQUIRED)
find_package(spdlog CONFIG REQUIRED)
find_package(nlohmann_json CONFIG REQUIRED)
if(NIMBUS_BUILD_TESTS)
  find_package(GTest CONFIG REQUIRED)
endif()

# Open MPI refuses to run as root unless told; tests and scripts set this, never the user.
set(NIMBUS_MPI_ENV
  OMPI_ALLOW_RUN_AS_ROOT=1
  OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
  OMPI_MCA_rmaps_base_oversubscribe=1
  OMPI_MCA_hwloc_base_binding_policy=none)
