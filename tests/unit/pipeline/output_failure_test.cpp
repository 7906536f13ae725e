// The outputs of a run are committed together (README "Outputs"): when any write fails, every
// rank throws the same Error and the folder holds no file of the run, final or temporary.
// Checked for an image whose final name cannot be taken (a folder is in the way: its rename
// fails after the HDF5 file, the sidecar and the EXR were ready) and for a full disk while the
// HDF5 file is written (a file size limit stands in for it, tests/support/file_size_limit.h).
// Two runs writing to one folder at the same time (one per rank, on MPI_COMM_SELF) both
// succeed: their temporaries have distinct names.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "io/output/hdf5_reader.h"
#include "io/output/image_io.h"
#include "io/scene/scene_toml.h"
#include "src/core/error.h"
#include "src/pipeline/pipeline.h"
#include "tests/support/expect_collective_error.h"
#include "tests/support/file_size_limit.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;

// An empty folder, the same on every rank (rank 0's pid), removed with the object.
class RunFolder {
public:
    explicit RunFolder(const std::string& tag) {
        int pid = static_cast<int>(::getpid());
        MPI_Bcast(&pid, 1, MPI_INT, 0, MPI_COMM_WORLD);
        path_ = (fs::temp_directory_path() / ("nimbus_output_failure_" + std::to_string(pid)) / tag)
                    .string();
        if (test::world_rank() == 0) {
            fs::remove_all(path_);
            fs::create_directories(path_);
        }
        MPI_Barrier(MPI_COMM_WORLD);
    }
    ~RunFolder() {
        MPI_Barrier(MPI_COMM_WORLD);
        std::error_code ec;
        if (test::world_rank() == 0) fs::remove_all(fs::path(path_).parent_path(), ec);
    }
    RunFolder(const RunFolder&) = delete;
    RunFolder& operator=(const RunFolder&) = delete;

    const std::string& path() const { return path_; }
    std::string file(const std::string& name) const { return path_ + "/" + name; }
    std::vector<std::string> names() const {
        std::vector<std::string> n;
        for (const auto& e : fs::directory_iterator(path_))
            n.push_back(e.path().filename().string());
        std::sort(n.begin(), n.end());
        return n;
    }

private:
    std::string path_;
};

Scene small_scene(const std::string& out) {
    Scene s =
        default_scene({"grid.n=[24,20,16]", "grid.cell_size=100.0", "camera.resolution=[48,32]"});
    s.output.dir = out;
    return s;
}

const std::vector<std::string> kAllOutputs = {"nimbus.exr", "nimbus.h5", "nimbus.png",
                                              "nimbus.xdmf"};

TEST(PipelineOutput, ImageThatCannotBeCommittedLeavesNoOutputOfTheRun) {
    RunFolder dir("png_is_a_folder");
    if (test::world_rank() == 0) fs::create_directory(dir.file("nimbus.png"));
    MPI_Barrier(MPI_COMM_WORLD);
    test::expect_collective_error([&] { run_pipeline(MPI_COMM_WORLD, small_scene(dir.path())); },
                                  "cannot write output file '" + dir.file("nimbus.png") + "'");
    if (test::world_rank() == 0) {
        EXPECT_EQ(dir.names(), std::vector<std::string>{"nimbus.png"});  // the folder only
    }
}

TEST(PipelineOutput, DiskFullDuringHdf5LeavesNothingAndTheNextRunWorks) {
    RunFolder dir("disk_full");
    {
        // Room for the file's first metadata, not for the first 30 KiB field.
        test::FileSizeLimit limit(96 * 1024);
        test::expect_collective_error(
            [&] { run_pipeline(MPI_COMM_WORLD, small_scene(dir.path())); },
            "cannot write output file '" + dir.file("nimbus.h5") +
                "', field 'density': File too large");
    }
    if (test::world_rank() == 0) {
        EXPECT_TRUE(dir.names().empty());
    }

    // The failed file was closed cleanly on every rank: the same run now succeeds.
    const RunResult r = run_pipeline(MPI_COMM_WORLD, small_scene(dir.path()));
    if (test::world_rank() != 0) return;
    EXPECT_EQ(dir.names(), kAllOutputs);
    EXPECT_EQ(read_field(r.hdf5_path, "fields/density").shape, (std::array<int, 3>{24, 20, 16}));
}

TEST(PipelineOutput, TwoRunsIntoOneFolderAtOnceBothSucceed) {
    // At 2 ranks: two independent runs at the same time, one per rank. (At 1 rank: one run.)
    RunFolder dir("race");
    RunResult r;
    EXPECT_NO_THROW(r = run_pipeline(MPI_COMM_SELF, small_scene(dir.path())));
    int ok = r.hdf5_path.empty() ? 0 : 1, all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    EXPECT_EQ(all, 1) << "a run failed";
    if (test::world_rank() != 0) return;
    EXPECT_EQ(dir.names(), kAllOutputs);  // whichever run renamed last; no temporary left
    EXPECT_EQ(read_field(dir.file("nimbus.h5"), "fields/density").shape,
              (std::array<int, 3>{24, 20, 16}));
    EXPECT_EQ(read_exr(dir.file("nimbus.exr")).width, 48);
}

}  // namespace
}  // namespace nimbus
