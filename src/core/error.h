// Errors: nimbus::Error carries a one-line, user-facing message. Collective helpers turn a
// local failure on any rank into the same failure on every rank, so no rank is left hanging.
#pragma once

#include <mpi.h>

#include <stdexcept>
#include <string>

namespace nimbus {

class Error : public std::runtime_error {
public:
    explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// Collective over comm. If any rank passes ok == false, every rank throws Error with the
// message of the lowest failing rank. Cheap: one MPI_Allreduce plus a broadcast on failure.
void check_collective(MPI_Comm comm, bool ok, const std::string& message);

// Runs fn(); an Error thrown on some ranks becomes the same Error on all ranks of comm.
template <class Fn>
void run_collective(MPI_Comm comm, Fn&& fn) {
    std::string msg;
    bool ok = true;
    try {
        fn();
    } catch (const std::exception& e) {
        ok = false;
        msg = e.what();
    }
    check_collective(comm, ok, msg);
}

}  // namespace nimbus
