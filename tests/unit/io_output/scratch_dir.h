// A scratch folder shared by every rank of MPI_COMM_WORLD, removed when the object dies.
// Collective: rank 0 creates it and broadcasts its name.
#pragma once

#include <mpi.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace nimbus::test {

class ScratchDir {
public:
    explicit ScratchDir(const std::string& tag) {
        int rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        std::string name;
        if (rank == 0) {
            static int counter = 0;
            name = (std::filesystem::temp_directory_path() /
                    ("nimbus_" + tag + "_" + std::to_string(::getpid()) + "_" +
                     std::to_string(counter++)))
                       .string();
            std::filesystem::remove_all(name);
            std::filesystem::create_directories(name);
        }
        int len = static_cast<int>(name.size());
        MPI_Bcast(&len, 1, MPI_INT, 0, MPI_COMM_WORLD);
        name.resize(static_cast<size_t>(len));
        MPI_Bcast(name.data(), len, MPI_CHAR, 0, MPI_COMM_WORLD);
        path_ = name;
    }
    ~ScratchDir() {
        MPI_Barrier(MPI_COMM_WORLD);
        int rank = 0;
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        std::error_code ec;
        if (rank == 0) std::filesystem::remove_all(path_, ec);
    }
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;

    const std::string& path() const { return path_; }
    std::string file(const std::string& name) const { return path_ + "/" + name; }

private:
    std::string path_;
};

}  // namespace nimbus::test
