// The commit protocol for every output file of a run (HDF5, XDMF, EXR, PNG): each file is
// written under a temporary name unique to the run, "<final>.<token>.tmp", and commit() renames
// them all to their final names only once every write has succeeded. A run that fails leaves no
// file under its final name and no temporary: the set removes its temporaries when destroyed
// uncommitted. The token (rank 0's pid and random bits, broadcast) keeps two runs writing to the
// same folder at once from sharing a temporary.
//
//   OutputFiles files(comm);
//   Hdf5Writer h5(d, grid, "out/nimbus.h5", files);   // registers nimbus.h5 and nimbus.xdmf
//   ... h5.close();
//   write_exr(files.add("out/nimbus.exr"), image);       // rank 0
//   files.commit();                                      // collective: all final, or none
#pragma once

#include <mpi.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace nimbus {

class OutputFiles {
public:
    // Collective over comm (not owned; it must stay valid for the constructor and commit(),
    // not for the destructor): agrees on the run's token.
    explicit OutputFiles(MPI_Comm comm);
    // Uncommitted: rank 0 removes every temporary. Not collective and no MPI call (a writer
    // that owns its set frees the communicator first); destroy the writers of the temporaries
    // (Hdf5Writer closes its file collectively) before the set.
    ~OutputFiles();
    OutputFiles(const OutputFiles&) = delete;
    OutputFiles& operator=(const OutputFiles&) = delete;

    // Not collective, but call it on every rank alike: registers final_path and returns the
    // temporary name to write it under.
    std::string add(const std::string& final_path);
    // message with every temporary name replaced by its final name, so that a write error
    // names the file the user asked for.
    std::string with_final_names(std::string message) const;
    // Collective: once every rank has entered it, rank 0 renames every temporary to its final
    // name, in the order added, replacing files of those names (a previous run's). If a final
    // name is not a file, or a rename fails, the folder is left as it was: the files already
    // renamed and the remaining temporaries are removed, the previous files restored, and every
    // rank throws the same Error.
    void commit();

    // Temporaries of `name` in `dir` (<name>.<ext>.<pid>-<8 hex>.tmp) whose process no longer
    // runs on this host: a killed run's (SIGKILL, an out-of-memory kill, MPI_Abort run no
    // cleanup). Their count and bytes. Not collective.
    struct Stale {
        int files = 0;
        std::uintmax_t bytes = 0;
    };
    static Stale stale_temporaries(const std::string& dir, const std::string& name);

private:
    std::string replace_finals();  // rank 0's part of commit(); the error, or empty

    MPI_Comm comm_;
    int rank_ = 0;  // in comm, kept for the destructor
    std::string token_;
    std::vector<std::pair<std::string, std::string>> files_;  // {temporary, final}
    bool committed_ = false;
};

}  // namespace nimbus
