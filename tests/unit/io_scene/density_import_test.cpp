// Density import from HDF5 and raw float32 files, on 1 and 2 ranks: every owned cell equals
// the file's value times the density scale, ghosts inside the domain (or across a periodic
// axis) hold the neighbour's value, ghosts outside are 0; every bad file is an Error on every
// rank. Files are written by rank 0 with plain serial calls, then read collectively.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "io/scene/density_import.h"
#include "src/core/bcast.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"
#include "tests/support/scratch_dir.h"

namespace nimbus {
namespace {

const Int3 kN{6, 5, 4};

// The test density: distinct at every cell, exact in float32.
double f(int i, int j, int k) { return 1.0 + i + 10.0 * j + 100.0 * k + 0.25; }

template <class T>
std::vector<T> values(const Int3& n, double nan_at = -1) {
    std::vector<T> v;
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i) v.push_back(static_cast<T>(f(i, j, k)));
    if (nan_at >= 0) v[static_cast<size_t>(nan_at)] = std::numeric_limits<T>::quiet_NaN();
    return v;
}

// Rank 0 writes dataset `name` of shape dims ([z][y][x]) and element type `type`; all wait.
template <class T>
void write_h5(const std::string& path, const std::string& name, const std::vector<hsize_t>& dims,
              hid_t type, const std::vector<T>& data) {
    if (test::world_rank() == 0) {
        const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
        const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
        const hid_t dset = H5Dcreate2(file, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        const hid_t mem = std::is_same_v<T, float> ? H5T_NATIVE_FLOAT
                        : std::is_same_v<T, double> ? H5T_NATIVE_DOUBLE : H5T_NATIVE_INT;
        H5Dwrite(dset, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data());
        H5Dclose(dset);
        H5Sclose(space);
        H5Fclose(file);
    }
    MPI_Barrier(MPI_COMM_WORLD);
}

// Rank 0 writes the floats little-endian (the test machine is little-endian); all wait.
void write_raw(const std::string& path, const std::vector<float>& data) {
    if (test::world_rank() == 0) {
        std::ofstream out(path, std::ios::binary);
        out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size() * 4));
    }
    MPI_Barrier(MPI_COMM_WORLD);
}

MediumSpec spec_for(MediumSpec::Kind kind, const std::string& file, double density = 1.0) {
    MediumSpec s;
    s.kind = kind;
    s.file = file;
    s.density = density;
    return s;
}

// Every cell of rho's allocated box: owned and in-domain ghosts = scale * f at the (wrapped)
// global cell; ghosts outside a non-periodic domain = 0.
void expect_density(const Field<double>& rho, const Decomposition& d, double scale) {
    int bad = 0;
    for_each_cell(rho.allocated(), [&](int i, int j, int k) {
        Int3 c{i, j, k};
        bool outside = false;
        for (int a = 0; a < 3; ++a) {
            if (c[a] >= 0 && c[a] < kN[a]) continue;
            if (d.periodic(a)) c[a] = (c[a] + kN[a]) % kN[a]; else outside = true;
        }
        const double expected = outside ? 0.0 : scale * f(c[0], c[1], c[2]);
        if (rho(i, j, k) != expected && ++bad <= 5)
            ADD_FAILURE() << "rank " << d.rank() << " cell (" << i << "," << j << "," << k << ") = "
                          << rho(i, j, k) << ", expected " << expected;
    });
    EXPECT_EQ(bad, 0);
}

// Runs fn, expects an Error on every rank with the same message containing every piece.
template <class Fn>
void expect_error_everywhere(Fn&& fn, std::initializer_list<std::string> pieces) {
    std::string msg;
    try {
        fn();
    } catch (const Error& e) {
        msg = e.what();
    }
    int caught = msg.empty() ? 0 : 1, total = 0;
    MPI_Allreduce(&caught, &total, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(total, test::world_size()) << "not every rank threw";
    const std::string root = bcast_string(MPI_COMM_WORLD, 0, msg);
    EXPECT_EQ(msg, root) << "ranks disagree";
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const auto& p : pieces) EXPECT_NE(msg.find(p), std::string::npos) << "missing '" << p << "' in: " << msg;
}

struct Layout {
    const char* name;
    Int3 dims;                   // process grid (0 = choose)
    std::array<bool, 3> periodic;
};

class DensityImport : public ::testing::TestWithParam<Layout> {
protected:
    Decomposition decomp() const { return Decomposition(MPI_COMM_WORLD, kN, GetParam().dims, GetParam().periodic); }
};

TEST_P(DensityImport, Hdf5DoubleDataset) {
    test::ScratchDir dir(std::string("h5d_") + GetParam().name);
    write_h5(dir.file("d.h5"), "density", {4, 5, 6}, H5T_IEEE_F64LE, values<double>(kN));
    const Decomposition d = decomp();
    Field<double> rho(d.local(), 1, 1, -7.0);  // garbage ghosts must be overwritten
    read_density(spec_for(MediumSpec::Kind::hdf5, dir.file("d.h5"), 2.0), d, rho);
    expect_density(rho, d, 2.0);
}

TEST_P(DensityImport, Hdf5Float32AndIntegerDatasetsAreConverted) {
    test::ScratchDir dir(std::string("h5f_") + GetParam().name);
    write_h5(dir.file("f.h5"), "rho", {4, 5, 6}, H5T_IEEE_F32BE, values<float>(kN));
    const Decomposition d = decomp();
    Field<double> rho;  // unallocated: read_density sizes it
    MediumSpec spec = spec_for(MediumSpec::Kind::hdf5, dir.file("f.h5"), 0.5);
    spec.dataset = "rho";
    read_density(spec, d, rho);
    EXPECT_EQ(rho.owned(), d.local());
    EXPECT_EQ(rho.ghost(), 1);
    expect_density(rho, d, 0.5);

    std::vector<int> ints;
    for (int k = 0; k < kN[2]; ++k)
        for (int j = 0; j < kN[1]; ++j)
            for (int i = 0; i < kN[0]; ++i) ints.push_back(static_cast<int>(std::floor(f(i, j, k))));
    write_h5(dir.file("i.h5"), "density", {4, 5, 6}, H5T_STD_I32LE, ints);
    read_density(spec_for(MediumSpec::Kind::hdf5, dir.file("i.h5")), d, rho);
    for_each_cell(d.local(), [&](int i, int j, int k) { EXPECT_EQ(rho(i, j, k), std::floor(f(i, j, k))); });
}

TEST_P(DensityImport, RawFloat32) {
    test::ScratchDir dir(std::string("raw_") + GetParam().name);
    write_raw(dir.file("d.raw"), values<float>(kN));
    const Decomposition d = decomp();
    Field<double> rho(d.local(), 1);
    read_density(spec_for(MediumSpec::Kind::raw, dir.file("d.raw"), 3.0), d, rho);
    expect_density(rho, d, 3.0);
}

INSTANTIATE_TEST_SUITE_P(
    Layouts, DensityImport,
    ::testing::Values(Layout{"slabs_z", {0, 0, 0}, {false, false, false}},
                      Layout{"split_x", {0, 1, 1}, {false, false, false}},
                      Layout{"periodic_xy", {0, 1, 1}, {true, true, false}}),
    [](const auto& p) { return std::string(p.param.name); });

TEST(DensityImportErrors, RawFileOfWrongSize) {
    test::ScratchDir dir("raw_size");
    std::vector<float> v = values<float>(kN);
    v.pop_back();
    write_raw(dir.file("short.raw"), v);
    const Decomposition d(MPI_COMM_WORLD, kN);
    Field<double> rho(d.local(), 1);
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::raw, dir.file("short.raw")), d, rho); },
                            {"short.raw", "has 476 bytes", "needs 480"});
}

TEST(DensityImportErrors, MissingFile) {
    test::ScratchDir dir("missing");
    const Decomposition d(MPI_COMM_WORLD, kN);
    Field<double> rho(d.local(), 1);
    for (auto kind : {MediumSpec::Kind::raw, MediumSpec::Kind::hdf5})
        expect_error_everywhere([&] { read_density(spec_for(kind, dir.file("none.dat")), d, rho); },
                                {"none.dat", "not found"});
}

TEST(DensityImportErrors, NotAnHdf5File) {
    test::ScratchDir dir("not_h5");
    write_raw(dir.file("d.h5"), values<float>(kN));
    const Decomposition d(MPI_COMM_WORLD, kN);
    Field<double> rho(d.local(), 1);
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::hdf5, dir.file("d.h5")), d, rho); },
                            {"d.h5", "cannot open as an HDF5 file"});
}

TEST(DensityImportErrors, NanInFile) {
    test::ScratchDir dir("nan");
    const int at = 3 + kN[0] * (2 + kN[1] * 3);  // cell (3, 2, 3): owned by the last rank
    write_raw(dir.file("nan.raw"), values<float>(kN, at));
    write_h5(dir.file("nan.h5"), "density", {4, 5, 6}, H5T_IEEE_F64LE, values<double>(kN, at));
    const Decomposition d(MPI_COMM_WORLD, kN);
    Field<double> rho(d.local(), 1);
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::raw, dir.file("nan.raw")), d, rho); },
                            {"nan.raw", "density at cell (3, 2, 3) is nan", "densities must be finite, >= 0 and at most 3.4e+38"});
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::hdf5, dir.file("nan.h5")), d, rho); },
                            {"nan.h5", "density at cell (3, 2, 3) is nan"});
}

TEST(DensityImportErrors, NegativeValueInFile) {
    test::ScratchDir dir("negative");
    std::vector<float> v = values<float>(kN);
    v[0] = -1.0f;
    write_raw(dir.file("neg.raw"), v);
    const Decomposition d(MPI_COMM_WORLD, kN);
    Field<double> rho(d.local(), 1);
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::raw, dir.file("neg.raw")), d, rho); },
                            {"density at cell (0, 0, 0) is -1"});
}

TEST(DensityImportErrors, MissingDataset) {
    test::ScratchDir dir("no_dataset");
    write_h5(dir.file("d.h5"), "other", {4, 5, 6}, H5T_IEEE_F64LE, values<double>(kN));
    const Decomposition d(MPI_COMM_WORLD, kN);
    Field<double> rho(d.local(), 1);
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::hdf5, dir.file("d.h5")), d, rho); },
                            {"d.h5", "dataset 'density' not found"});
    MediumSpec nested = spec_for(MediumSpec::Kind::hdf5, dir.file("d.h5"));
    nested.dataset = "group/density";
    expect_error_everywhere([&] { read_density(nested, d, rho); }, {"dataset 'group/density' not found"});
}

TEST(DensityImportErrors, DatasetShapeMustMatchTheGrid) {
    test::ScratchDir dir("shape");
    write_h5(dir.file("d.h5"), "density", {4, 6, 5}, H5T_IEEE_F64LE, values<double>(kN));
    write_h5(dir.file("flat.h5"), "density", {120}, H5T_IEEE_F64LE, values<double>(kN));
    const Decomposition d(MPI_COMM_WORLD, kN);
    Field<double> rho(d.local(), 1);
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::hdf5, dir.file("d.h5")), d, rho); },
                            {"has shape [4][6][5] but the grid needs [nz][ny][nx] = [4][5][6]"});
    expect_error_everywhere([&] { read_density(spec_for(MediumSpec::Kind::hdf5, dir.file("flat.h5")), d, rho); },
                            {"has 1 dimensions but must have 3"});
}

}  // namespace
}  // namespace nimbus
