// PETSc start-up and error checks shared by the PETSc users (the diffusion cross-check path and
// DOM's GMRES). Not collective except ensure_petsc, which every rank of comm calls.
#pragma once

#include <petscsys.h>

#include <fmt/format.h>

#include "src/core/error.h"

namespace nimbus::petsc {

// Throws Error naming `who` (e.g. "dom (gmres)") and the call when PETSc reports an error.
inline void check(PetscErrorCode ierr, const char* who, const char* what) {
    if (ierr != 0)
        throw Error(fmt::format("{}: {} failed with PETSc error {}", who, what, static_cast<int>(ierr)));
}

// PETSc is initialized here only if the program has not done it, on the given communicator.
inline void ensure_initialized(MPI_Comm comm) {
    PetscBool done = PETSC_FALSE;
    check(PetscInitialized(&done), "petsc", "PetscInitialized");
    if (done) return;
    PETSC_COMM_WORLD = comm;
    check(PetscInitializeNoArguments(), "petsc", "PetscInitialize");
}

}  // namespace nimbus::petsc
