// For failure paths that must be collective: every rank throws an Error, with the same message
// on every rank, and that message contains `part`. A rank left behind would hang the test
// (ctest's timeout reports it).
#pragma once

#include <gtest/gtest.h>
#include <mpi.h>

#include <functional>
#include <string>

#include "src/core/bcast.h"
#include "src/core/error.h"

namespace nimbus::test {

inline void expect_collective_error(const std::function<void()>& fn, const std::string& part,
                                    MPI_Comm comm = MPI_COMM_WORLD) {
    std::string message;
    try {
        fn();
    } catch (const Error& e) {
        message = e.what();
    }
    EXPECT_NE(message.find(part), std::string::npos) << "message: '" << message << "'";
    const std::string first = bcast_string(comm, 0, message);
    int same = first == message ? 1 : 0, all = 0;
    MPI_Allreduce(&same, &all, 1, MPI_INT, MPI_MIN, comm);
    EXPECT_EQ(all, 1) << "the ranks threw different errors (this one: '" << message << "')";
}

}  // namespace nimbus::test
