// The commit protocol (OutputFiles) and the HDF5 writer's failure paths, at 1 and 2 ranks:
// temporaries are unique per run and agreed by every rank; nothing is final before commit;
// a failing rename rolls the whole set back; a write that runs out of space (a file size
// limit, tests/support/file_size_limit.h, standing in for a full disk) throws the same Error
// on every rank, leaves no file behind and no HDF5 state that hangs or crashes later (a
// following write succeeds, and the binary exits cleanly through MPI_Finalize).
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "io/output/hdf5_reader.h"
#include "io/output/hdf5_writer.h"
#include "io/output/output_files.h"
#include "tests/unit/io_output/sample_fields.h"
#include "tests/support/scratch_dir.h"
#include "src/core/bcast.h"
#include "src/core/error.h"
#include "tests/support/expect_collective_error.h"
#include "tests/support/file_size_limit.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;
using test::expect_collective_error;
using test::FileSizeLimit;
using test::ScratchDir;

// The names in a folder, sorted.
std::vector<std::string> listing(const std::string& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

TEST(OutputFiles, TemporariesAreUniquePerRunAndAgreedByEveryRank) {
    ScratchDir dir("outfiles_names");
    const std::string final_path = dir.file("nimbus.h5");
    OutputFiles a(MPI_COMM_WORLD), b(MPI_COMM_WORLD);
    const std::string ta = a.add(final_path), tb = b.add(final_path);
    EXPECT_NE(ta, tb);
    EXPECT_NE(ta, final_path + ".tmp");  // the old fixed name, shared by concurrent runs
    EXPECT_EQ(fs::path(ta).parent_path(),
              fs::path(final_path).parent_path());  // same folder: rename
    EXPECT_EQ(ta.rfind(final_path, 0), 0u) << ta;   // recognisable: starts with the final name

    const std::string t0 = bcast_string(MPI_COMM_WORLD, 0, ta);
    EXPECT_EQ(t0, ta) << "ranks disagree on the temporary name";

    EXPECT_EQ(a.with_final_names("cannot write '" + ta + "': full"),
              "cannot write '" + final_path + "': full");
}

TEST(OutputFiles, CommitMakesEveryFileFinalTogether) {
    ScratchDir dir("outfiles_commit");
    OutputFiles files(MPI_COMM_WORLD);
    const std::string a = files.add(dir.file("a.txt")), b = files.add(dir.file("b.txt"));
    if (test::world_rank() == 0) {
        std::ofstream(a) << "a";
        std::ofstream(b) << "b";
    }
    MPI_Barrier(MPI_COMM_WORLD);
    EXPECT_FALSE(fs::exists(dir.file("a.txt")));
    files.commit();
    EXPECT_TRUE(fs::exists(dir.file("a.txt")));
    EXPECT_TRUE(fs::exists(dir.file("b.txt")));
    EXPECT_FALSE(fs::exists(a));
    EXPECT_THROW(files.commit(), Error);
}

TEST(OutputFiles, UncommittedSetRemovesItsTemporaries) {
    ScratchDir dir("outfiles_abandon");
    std::string a;
    {
        OutputFiles files(MPI_COMM_WORLD);
        a = files.add(dir.file("a.txt"));
        if (test::world_rank() == 0) std::ofstream(a) << "a";
        MPI_Barrier(MPI_COMM_WORLD);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    if (test::world_rank() == 0) {
        EXPECT_TRUE(listing(dir.path()).empty());
    }
}

TEST(OutputFiles, FailedRenameRollsBackTheWholeSet) {
    // The last file's final name is a folder: its rename fails after the others succeeded.
    ScratchDir dir("outfiles_rollback");
    if (test::world_rank() == 0) fs::create_directory(dir.file("c.txt"));
    OutputFiles files(MPI_COMM_WORLD);
    const std::string a = files.add(dir.file("a.txt")), b = files.add(dir.file("b.txt")),
                      c = files.add(dir.file("c.txt"));
    if (test::world_rank() == 0)
        for (const std::string& t : {a, b, c}) std::ofstream(t) << "x";
    MPI_Barrier(MPI_COMM_WORLD);
    expect_collective_error([&] { files.commit(); },
                            "cannot write output file '" + dir.file("c.txt") + "'");
    if (test::world_rank() == 0) {
        EXPECT_EQ(listing(dir.path()), std::vector<std::string>{"c.txt"});
    }
}

// The contents of a small file.
std::string slurp(const std::string& path) {
    std::ifstream f(path);
    return std::string(std::istreambuf_iterator<char>(f), {});
}

// A previous run's files are replaced on success, and survive a failed commit: the folder then
// holds the previous set as it was (it used to lose the files renamed over before the failure).
TEST(OutputFiles, CommitReplacesAPreviousRunOrLeavesItWhole) {
    ScratchDir dir("outfiles_previous");
    const std::string fa = dir.file("a.txt"), fb = dir.file("b.txt");
    if (test::world_rank() == 0) std::ofstream(fa) << "old a", std::ofstream(fb) << "old b";
    {
        // b's temporary is never written: its rename fails after a's succeeded.
        OutputFiles files(MPI_COMM_WORLD);
        const std::string a = files.add(fa);
        files.add(fb);
        if (test::world_rank() == 0) std::ofstream(a) << "new a";
        MPI_Barrier(MPI_COMM_WORLD);
        expect_collective_error([&] { files.commit(); }, "cannot write output file '" + fb + "'");
    }
    if (test::world_rank() == 0) {
        EXPECT_EQ(listing(dir.path()), (std::vector<std::string>{"a.txt", "b.txt"}));
        EXPECT_EQ(slurp(fa), "old a");
        EXPECT_EQ(slurp(fb), "old b");
    }
    MPI_Barrier(MPI_COMM_WORLD);
    {
        OutputFiles files(MPI_COMM_WORLD);
        const std::string a = files.add(fa), b = files.add(fb);
        if (test::world_rank() == 0) std::ofstream(a) << "new a", std::ofstream(b) << "new b";
        MPI_Barrier(MPI_COMM_WORLD);
        files.commit();
    }
    if (test::world_rank() == 0) {
        EXPECT_EQ(listing(dir.path()), (std::vector<std::string>{"a.txt", "b.txt"}));  // no backups left
        EXPECT_EQ(slurp(fa), "new a");
        EXPECT_EQ(slurp(fb), "new b");
    }
}

// A final name that is a folder is refused before anything is renamed: the previous file of
// the set stays.
TEST(OutputFiles, AFinalNameThatIsAFolderLeavesThePreviousFiles) {
    ScratchDir dir("outfiles_folder");
    if (test::world_rank() == 0) {
        std::ofstream(dir.file("a.txt")) << "old a";
        fs::create_directory(dir.file("b.txt"));
    }
    OutputFiles files(MPI_COMM_WORLD);
    const std::string a = files.add(dir.file("a.txt")), b = files.add(dir.file("b.txt"));
    if (test::world_rank() == 0) std::ofstream(a) << "new a", std::ofstream(b) << "new b";
    MPI_Barrier(MPI_COMM_WORLD);
    expect_collective_error([&] { files.commit(); },
                            "cannot write output file '" + dir.file("b.txt") + "': it exists and is not a file");
    if (test::world_rank() == 0) {
        EXPECT_EQ(listing(dir.path()), (std::vector<std::string>{"a.txt", "b.txt"}));
        EXPECT_EQ(slurp(dir.file("a.txt")), "old a");
        EXPECT_TRUE(fs::is_directory(dir.file("b.txt")));
    }
}

// What each HDF5 writer test starts from: a scratch folder, a grid split over all ranks, and the
// path of the file to write in the folder.
struct WriterScene {
    ScratchDir dir;
    Grid grid;
    Decomposition d;
    std::string path;
    WriterScene(const std::string& folder, const Grid& g, const std::string& file)
        : dir(folder), grid(g), d(MPI_COMM_WORLD, g.n), path(dir.file(file)) {}
};

TEST(Hdf5Writer, NothingFinalUntilTheSetCommits) {
    WriterScene s("outfiles_h5", test::sample_grid(), "run.h5");
    auto& [dir, grid, d, path] = s;
    OutputFiles files(MPI_COMM_WORLD);
    {
        Hdf5Writer w(d, grid, path, files);
        test::write_sample_fields(w, d);
        MPI_Barrier(MPI_COMM_WORLD);
        EXPECT_TRUE(fs::exists(w.temporary_path()));
        w.close();
        EXPECT_THROW(w.commit(), Error);  // the set commits, not the writer
        EXPECT_THROW(w.write_string_attribute("/run", "late", "x"), Error);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    EXPECT_FALSE(fs::exists(path));
    EXPECT_FALSE(fs::exists(dir.file("run.xdmf")));
    files.commit();
    EXPECT_TRUE(fs::exists(dir.file("run.xdmf")));
    if (test::world_rank() == 0) {
        EXPECT_EQ(listing(dir.path()), (std::vector<std::string>{"run.h5", "run.xdmf"}));
        EXPECT_EQ(read_field(path, "fields/density").shape, grid.n);
    }
}

// A value that float32 cannot hold (1e300, a density a run takes in double) or a NaN, on one
// rank only: every rank throws the same Error naming the field and the count, and nothing is left.
TEST(Hdf5Writer, NonFiniteValuesAreRefusedOnEveryRankAndLeaveNothing) {
    for (const double v : {1e300, std::numeric_limits<double>::quiet_NaN()}) {
        WriterScene s("outfiles_nonfinite", test::sample_grid(), "bad.h5");
        auto& [dir, grid, d, path] = s;
        {
            OutputFiles files(MPI_COMM_WORLD);
            Hdf5Writer w(d, grid, path, files);
            Field<double> f = test::sample_field(d, 1, 0.0);
            const Int3 last{grid.n[0] - 1, grid.n[1] - 1, grid.n[2] - 1};  // on the last rank
            if (d.local().contains(last[0], last[1], last[2])) f(last[0], last[1], last[2]) = v;
            expect_collective_error([&] { w.write_field("density", f, "1", "density"); },
                                    "output file '" + path + "', field 'density': 1 value(s) are NaN, Inf or "
                                    "beyond float32's range");
        }
        MPI_Barrier(MPI_COMM_WORLD);
        if (test::world_rank() == 0) {
            EXPECT_TRUE(listing(dir.path()).empty()) << v;
        }
        MPI_Barrier(MPI_COMM_WORLD);
    }
}

// A grid whose fields (64 KiB of float32 each) do not fit under a 96 KiB file size limit.
Grid big_grid() {
    Grid g = test::sample_grid();
    g.n = {32, 32, 16};
    return g;
}

TEST(Hdf5Writer, OutOfSpaceInAFieldFailsOnEveryRankAndLeavesNothing) {
    WriterScene s("outfiles_full_field", big_grid(), "full.h5");
    auto& [dir, grid, d, path] = s;
    {
        OutputFiles files(MPI_COMM_WORLD);
        FileSizeLimit limit(96 * 1024);
        Hdf5Writer w(d, grid, path, files);
        expect_collective_error(
            [&] { w.write_field("density", test::sample_field(d, 1, 0.0), "1", "density"); },
            "cannot write output file '" + path + "', field 'density': File too large");
    }
    MPI_Barrier(MPI_COMM_WORLD);
    if (test::world_rank() == 0) {
        EXPECT_TRUE(listing(dir.path()).empty());
    }

    // HDF5 closed the failed file cleanly: the same path can be written again.
    Hdf5Writer again(d, grid, path);
    again.write_field("density", test::sample_field(d, 1, 0.0), "1", "density");
    again.commit();
    if (test::world_rank() == 0) {
        EXPECT_EQ(read_field(path, "fields/density").shape, grid.n);
    }
}

TEST(Hdf5Writer, OutOfSpaceInAnAttributeFailsOnEveryRankAndLeavesNothing) {
    WriterScene s("outfiles_full_attr", test::sample_grid(), "full.h5");
    auto& [dir, grid, d, path] = s;
    {
        OutputFiles files(MPI_COMM_WORLD);
        FileSizeLimit limit(512 * 1024);
        Hdf5Writer w(d, grid, path, files);
        test::write_sample_fields(w, d);  // small: fits
        expect_collective_error(
            [&] { w.write_string_attribute("/run", "report", std::string(1 << 20, 'x')); },
            "attribute 'report' of '/run': File too large");
    }
    MPI_Barrier(MPI_COMM_WORLD);
    if (test::world_rank() == 0) {
        EXPECT_TRUE(listing(dir.path()).empty());
    }
}

}  // namespace
}  // namespace nimbus
