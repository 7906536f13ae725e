// A scratch folder for one test, the same path on every rank: created by rank 0 under the
// working directory (the build tree when run by ctest), broadcast, removed at the end.
// Collective over MPI_COMM_WORLD (constructor and destructor).
#pragma once

#include <mpi.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace nimbus::test {

class TempDir {
public:
    explicit TempDir(const std::string& name) {
        int rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        std::string p;
        if (rank == 0) {
            p = (std::filesystem::current_path() /
                 ("nimbus_test_" + std::to_string(getpid()) + "_" + name)).string();
            std::filesystem::remove_all(p);
            std::filesystem::create_directories(p);
        }
        int len = static_cast<int>(p.size());
        MPI_Bcast(&len, 1, MPI_INT, 0, MPI_COMM_WORLD);
        p.resize(static_cast<size_t>(len));
        MPI_Bcast(p.data(), len, MPI_CHAR, 0, MPI_COMM_WORLD);
        path_ = p;
        rank_ = rank;
    }
    ~TempDir() {
        MPI_Barrier(MPI_COMM_WORLD);
        if (rank_ == 0) {
            std::error_code ec;
            std::filesystem::remove_all(path_, ec);
        }
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    const std::filesystem::path& path() const { return path_; }
    std::string file(const std::string& name) const { return (path_ / name).string(); }

private:
    std::filesystem::path path_;
    int rank_ = 0;
};

}  // namespace nimbus::test
