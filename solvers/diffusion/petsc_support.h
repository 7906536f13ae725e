// PETSc start-up, error checks and owning handles shared by the PETSc users (the diffusion
// cross-check path and DOM's GMRES). Not collective except ensure_initialized, which every
// rank of comm calls.
#pragma once

#include <petscksp.h>
#include <petscsys.h>

#include <fmt/format.h>

#include "src/core/error.h"

namespace nimbus::petsc {

// Throws Error naming `who` (e.g. "dom (gmres)") and the call when PETSc reports an error.
inline void check(PetscErrorCode ierr, const char* who, const char* what) {
    if (ierr != 0)
        throw Error(fmt::format("{}: {} failed with PETSc error {}", who, what, static_cast<int>(ierr)));
}

// PETSc is initialized here only if the program has not done it, collectively over the ranks of
// comm (a solve may run on a sub-communicator, e.g. MPI_COMM_SELF). PETSC_COMM_WORLD becomes a
// duplicate of comm: comm is usually a Decomposition's, freed with it, and PETSc keeps its world
// until the end of the program.
inline void ensure_initialized(MPI_Comm comm) {
    PetscBool done = PETSC_FALSE;
    check(PetscInitialized(&done), "petsc", "PetscInitialized");
    if (done) return;
    MPI_Comm world = MPI_COMM_NULL;
    MPI_Comm_dup(comm, &world);
    PETSC_COMM_WORLD = world;
    check(PetscInitializeNoArguments(), "petsc", "PetscInitialize");
}

// Owning handles: destroyed at scope exit, also when an error unwinds the scope.
struct OptionsHandle {
    PetscOptions o = nullptr;
    ~OptionsHandle() { if (o) PetscOptionsDestroy(&o); }
};
struct MatHandle {
    Mat m = nullptr;
    ~MatHandle() { if (m) MatDestroy(&m); }
};
struct VecHandle {
    Vec v = nullptr;
    ~VecHandle() { if (v) VecDestroy(&v); }
};
struct KSPHandle {
    KSP ksp = nullptr;
    ~KSPHandle() { if (ksp) KSPDestroy(&ksp); }
};

}  // namespace nimbus::petsc
