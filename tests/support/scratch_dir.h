// A scratch folder for one test, the same path on every rank of MPI_COMM_WORLD: created by rank
// 0 under the system's temporary folder (unique per process and object), broadcast, removed when
// the object dies. Collective over MPI_COMM_WORLD (constructor and destructor).
#pragma once

#include <mpi.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "src/core/bcast.h"

namespace nimbus::test {

class ScratchDir {
public:
    explicit ScratchDir(const std::string& tag) {
        MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
        std::string name;
        if (rank_ == 0) {
            static int counter = 0;
            name = (std::filesystem::temp_directory_path() /
                    ("nimbus_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++)))
                       .string();
            std::filesystem::remove_all(name);
            std::filesystem::create_directories(name);
        }
        path_ = bcast_string(MPI_COMM_WORLD, 0, name);
    }
    ~ScratchDir() {
        MPI_Barrier(MPI_COMM_WORLD);
        std::error_code ec;
        if (rank_ == 0) std::filesystem::remove_all(path_, ec);
    }
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;

    const std::filesystem::path& path() const { return path_; }
    std::string file(const std::string& name) const { return (path_ / name).string(); }

private:
    std::filesystem::path path_;
    int rank_ = 0;
};

}  // namespace nimbus::test
