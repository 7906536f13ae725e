// Density import (see density_import.h). Both formats are read collectively, each rank its
// own box only:
//   hdf5: parallel HDF5 (MPI-IO driver on d.comm()), a hyperslab of the [nz][ny][nx] dataset
//         per rank, converted by HDF5 to double, collective transfer.
//   raw : MPI-IO with a subarray file view of the [nz][ny][nx] float32 array, read_all.
// Every check is collective (check_collective), so all ranks throw the same Error together.
#include "io/scene/density_import.h"

#include <fmt/format.h>
#include <hdf5.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <new>
#include <vector>

#include "io/hdf5_handle.h"
#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/mpi_counts.h"
#include "src/core/mpi_io_path.h"
#include "src/scene/medium.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;

// Rank 0 checks that the file exists (and, for raw, its size); the verdict is collective.
void check_file(const MediumSpec& spec, MPI_Comm comm, std::int64_t raw_bytes) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    std::string msg;
    if (rank == 0) {
        std::error_code ec;
        if (spec.file.empty()) {
            msg = fmt::format("medium.kind = \"{}\" needs medium.file", to_string(spec.kind));
        } else if (!fs::is_regular_file(spec.file, ec)) {
            msg = fmt::format("{}: density file not found", spec.file);
        } else if (const std::string abs = fs::absolute(spec.file, ec).lexically_normal().string();
                   abs.size() > kMaxMpiIoPath) {
            msg = fmt::format("{}: the density file's path is {} characters long, more than the {} nimbus can "
                              "open (Open MPI's MPI-IO aborts on file paths of about 245): move it, or link it "
                              "from a shorter path",
                              spec.file, abs.size(), kMaxMpiIoPath);
        } else if (raw_bytes >= 0) {
            const auto size = static_cast<std::int64_t>(fs::file_size(spec.file, ec));
            if (ec || size != raw_bytes)
                msg = fmt::format("{}: raw density file has {} bytes but the grid needs {} "
                                  "(4 * nx * ny * nz, float32, x fastest)",
                                  spec.file, ec ? -1 : size, raw_bytes);
        }
    }
    check_collective(comm, msg.empty(), msg);
}

// Reads the rank's box into `values` ([z][y][x] of the owned box) from the HDF5 dataset.
void read_hdf5(const MediumSpec& spec, const Decomposition& d, std::vector<double>& values) {
    const MPI_Comm comm = d.comm();
    const Box& b = d.local();
    const Int3& n = d.global().hi;
    const h5::QuietErrors quiet;

    const h5::Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    check_collective(comm, H5Pset_fapl_mpio(fapl.get(), comm, MPI_INFO_NULL) >= 0, h5::kNoMpioDriver);
    const h5::Handle file(H5Fopen(spec.file.c_str(), H5F_ACC_RDONLY, fapl.get()), H5Fclose);
    check_collective(comm, file.valid(), fmt::format("{}: cannot open as an HDF5 file", spec.file));

    const htri_t exists = H5Lexists(file.get(), spec.dataset.c_str(), H5P_DEFAULT);
    const h5::Handle dset(exists > 0 ? H5Dopen2(file.get(), spec.dataset.c_str(), H5P_DEFAULT) : -1, H5Dclose);
    check_collective(comm, dset.valid(),
                     fmt::format("{}: dataset '{}' not found (medium.dataset)", spec.file, spec.dataset));

    const h5::Handle type(H5Dget_type(dset.get()), H5Tclose);
    const H5T_class_t cls = H5Tget_class(type.get());
    check_collective(comm, cls == H5T_FLOAT || cls == H5T_INTEGER,
                     fmt::format("{}: dataset '{}' must hold numbers (floating point or integer)",
                                 spec.file, spec.dataset));

    const h5::Handle fspace(H5Dget_space(dset.get()), H5Sclose);
    const int ndims = H5Sget_simple_extent_ndims(fspace.get());
    hsize_t dims[3] = {0, 0, 0};
    if (ndims == 3) H5Sget_simple_extent_dims(fspace.get(), dims, nullptr);
    const bool shape_ok = ndims == 3 && dims[0] == static_cast<hsize_t>(n[2]) &&
                          dims[1] == static_cast<hsize_t>(n[1]) && dims[2] == static_cast<hsize_t>(n[0]);
    check_collective(comm, shape_ok,
                     ndims == 3 ? fmt::format("{}: dataset '{}' has shape [{}][{}][{}] but the grid needs "
                                              "[nz][ny][nx] = [{}][{}][{}]",
                                              spec.file, spec.dataset, dims[0], dims[1], dims[2], n[2], n[1], n[0])
                                : fmt::format("{}: dataset '{}' has {} dimensions but must have 3 ([nz][ny][nx])",
                                              spec.file, spec.dataset, ndims));

    const hsize_t start[3] = {static_cast<hsize_t>(b.lo[2]), static_cast<hsize_t>(b.lo[1]),
                              static_cast<hsize_t>(b.lo[0])};
    const hsize_t count[3] = {static_cast<hsize_t>(b.size(2)), static_cast<hsize_t>(b.size(1)),
                              static_cast<hsize_t>(b.size(0))};
    const herr_t selected = H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr);
    const h5::Handle mspace(H5Screate_simple(3, count, nullptr), H5Sclose);
    const h5::Handle dxpl(H5Pcreate(H5P_DATASET_XFER), H5Pclose);
    const herr_t collective = H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE);
    values.assign(static_cast<size_t>(b.cells()), 0.0);
    // Every rank takes part in the (collective) read whatever its own set-up gave.
    const herr_t status = H5Dread(dset.get(), H5T_NATIVE_DOUBLE, mspace.get(), fspace.get(), dxpl.get(),
                                  values.data());
    check_collective(comm, status >= 0 && selected >= 0 && collective >= 0,
                     fmt::format("{}: reading dataset '{}' failed", spec.file, spec.dataset));
}

// Reads the rank's box into `values` from the raw float32 little-endian file.
void read_raw(const MediumSpec& spec, const Decomposition& d, std::vector<double>& values) {
    const MPI_Comm comm = d.comm();
    const Box& b = d.local();
    const Int3& n = d.global().hi;

    MPI_File fh = MPI_FILE_NULL;
    const int rc = MPI_File_open(comm, spec.file.c_str(), MPI_MODE_RDONLY, MPI_INFO_NULL, &fh);
    check_collective(comm, rc == MPI_SUCCESS, fmt::format("{}: cannot open the raw density file", spec.file));

    const int sizes[3] = {n[2], n[1], n[0]};
    const int sub[3] = {b.size(2), b.size(1), b.size(0)};
    const int starts[3] = {b.lo[2], b.lo[1], b.lo[0]};
    MPI_Datatype view = MPI_DATATYPE_NULL;
    MPI_Type_create_subarray(3, sizes, sub, starts, MPI_ORDER_C, MPI_FLOAT, &view);
    MPI_Type_commit(&view);
    MPI_File_set_view(fh, 0, MPI_FLOAT, view, "native", MPI_INFO_NULL);

    std::vector<float> buf(static_cast<size_t>(b.cells()));
    // A box may hold more than 2^31 - 1 cells: one derived element then (mpi_counts.h).
    const LargeCount whole(b.cells(), MPI_FLOAT);
    MPI_Status st;
    const int rrc = MPI_File_read_all(fh, buf.data(), whole.count(), whole.type(), &st);
    MPI_Count got = 0;
    MPI_Get_elements_x(&st, whole.type(), &got);
    MPI_File_close(&fh);
    MPI_Type_free(&view);
    check_collective(comm, rrc == MPI_SUCCESS && got == static_cast<MPI_Count>(b.cells()),
                     fmt::format("{}: reading the raw density file failed", spec.file));

    values.resize(buf.size());
    for (size_t c = 0; c < buf.size(); ++c) {
        float v = buf[c];
        if constexpr (std::endian::native == std::endian::big) {
            std::uint32_t u = 0;
            std::memcpy(&u, &v, 4);
            u = __builtin_bswap32(u);
            std::memcpy(&v, &u, 4);
        }
        values[c] = static_cast<double>(v);
    }
}

}  // namespace

void read_density(const MediumSpec& spec, const Decomposition& d, Field<double>& rho) {
    const bool raw = spec.kind == MediumSpec::Kind::raw;
    check_collective(d.comm(), raw || spec.kind == MediumSpec::Kind::hdf5,
                     fmt::format("read_density: medium kind '{}' is not imported from a file", to_string(spec.kind)));
    const Int3& n = d.global().hi;
    check_file(spec, d.comm(), raw ? 4LL * n[0] * n[1] * n[2] : -1);

    std::vector<double> values;
    if (raw) read_raw(spec, d, values); else read_hdf5(spec, d, values);

    if (rho.owned() != d.local()) rho = Field<double>(d.local(), std::max(1, rho.ghost()));
    rho.fill(0.0);
    size_t c = 0;
    for_each_cell(d.local(), [&](int i, int j, int k) { rho(i, j, k) = spec.density * values[c++]; });
    exchange_halo(rho, d);
    try {
        check_density(rho, d);
    } catch (const Error& e) {
        throw Error(fmt::format("{}: {}", spec.file, e.what()));  // same text on every rank
    }
}

Medium load_medium(const Scene& scene, const Decomposition& d) {
    Medium m;
    m.grid = make_grid(scene.grid);
    m.bands = scene.bands;
    // Collectively: a rank that cannot allocate its box must not leave the others waiting in
    // the next collective (main() would have to MPI_Abort, skipping every cleanup).
    run_collective(d.comm(), [&] {
        try {
            m.rho = Field<double>(d.local(), 1, 1, 0.0);
        } catch (const std::bad_alloc&) {
            throw Error(fmt::format("not enough memory for the density ({:.1f} GiB per rank); use more ranks "
                                    "(on more nodes) or a smaller grid",
                                    static_cast<double>(d.local().grown(1).cells()) * 8 / (1 << 30)));
        }
    });
    if (scene.medium.kind == MediumSpec::Kind::hdf5 || scene.medium.kind == MediumSpec::Kind::raw) {
        read_density(scene.medium, d, m.rho);  // checked there, naming the file
    } else {
        fill_procedural_density(scene.medium, d, m.rho);
        check_density(m.rho, d);
    }
    return m;
}

}  // namespace nimbus
