// Parallel HDF5 writer (see hdf5_writer.h for the file layout).
//
// Life cycle, every step collective over the decomposition's communicator:
//   1. rank 0 checks that the target folder exists and is writable, and tells everyone
//      (so that no rank can be left inside a collective H5Fcreate that failed elsewhere);
//   2. H5Fcreate of the temporary name given by the run's OutputFiles, MPI-IO driver;
//   3. write_field: dataset float32 [nz][ny][nx](,3) of the global grid, each rank writes its
//      owned box as a hyperslab with a collective transfer; string attributes units/description;
//   4. close: H5Fclose, then rank 0 writes the XDMF sidecar under its temporary name; the
//      set's commit() renames both with the run's other outputs.
// Every write ends with an agreement (check_collective): all ranks succeed or all throw the
// same Error. Without close the destructor closes the file on every rank; the set removes
// the temporaries.
//
// Disk space. Parallel HDF5 cannot survive a write that fails on some ranks only: its metadata
// cache sync points (H5AC, run by H5Fclose and whenever dirty metadata piles up) skip their
// closing barrier or broadcast on error, so the ranks deadlock, and a failed H5Fclose leaves a
// file that crashes HDF5 at MPI_Finalize. A full disk (or quota, or file size limit) is the
// usual such failure. So before each call that can grow the file, rank 0 asks the file system
// for the blocks (fallocate) of what the call may add, and every rank learns the outcome: HDF5
// writes only into blocks already held, and the error path closes a file whose metadata fits
// in them. H5Fclose cuts the file back to its real end. On file systems without fallocate
// nothing is reserved (best effort).
//
// String attributes are scalar variable-length UTF-8 strings: the object header holds only a
// heap reference, the text lives in the global heap, so values far above the 64 KiB compact
// attribute limit (a JSON report, a TOML scene) need no dense attribute storage.
#include "io/output/hdf5_writer.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <new>
#include <system_error>
#include <vector>

#include "io/output/hdf5_detail.h"
#include "io/output/xdmf.h"
#include "src/core/error.h"

namespace nimbus {

namespace fs = std::filesystem;

namespace {

// Room reserved beyond a write's own bytes for the metadata it adds (object headers, group
// B-trees and heaps, global heap collections); a field adds a few KiB.
constexpr hsize_t kMetadataSlack = 64 * 1024;

}  // namespace

struct Hdf5Writer::Impl {
    Impl(const Decomposition& d_in, const Grid& grid_in) : d(d_in), grid(grid_in) {}

    Decomposition d;  // a copy: shares (and keeps alive) the communicator
    Grid grid;
    std::string tmp_path, xdmf_path, xdmf_tmp_path;
    h5::Handle file;
    std::vector<XdmfField> fields;  // in write order, for the XDMF sidecar
    bool closed = false;
    hsize_t reserved = 0;     // rank 0: bytes [0, reserved) of the file hold disk blocks
    bool can_reserve = true;  // rank 0: false once the file system said it cannot

    // Collective: before a call that adds up to `bytes` (plus metadata) to the file.
    void reserve(hsize_t bytes, const std::string& where);
};

namespace {

std::string folder_of(const std::string& path) {
    fs::path dir = fs::path(path).parent_path();
    return dir.empty() ? std::string(".") : dir.string();
}

bool folder_writable(const std::string& dir) {
    std::error_code ec;
    return fs::is_directory(dir, ec) && ::access(dir.c_str(), W_OK | X_OK) == 0;
}

std::string cannot_write(const std::string& path) {
    return "cannot write output file '" + path + "': folder '" + folder_of(path) +
           "' does not exist or is not writable";
}

bool valid_field_name(const std::string& name) {
    const auto parts = h5::split_path(name);
    if (parts.empty() || name.front() == '/') return false;
    for (const std::string& p : parts)
        if (p == "." || p == "..") return false;
    return true;
}

// Makes the file system hold blocks for bytes [from, to) of path, extending the file.
// Returns 0 or an errno (EOPNOTSUPP: the file system cannot).
int allocate_blocks(const std::string& path, hsize_t from, hsize_t to) {
    const int fd = ::open(path.c_str(), O_WRONLY);
    if (fd < 0) return errno;
    int err = 0;
    if (::fallocate(fd, 0, static_cast<off_t>(from), static_cast<off_t>(to - from)) != 0)
        err = errno;
    ::close(fd);
    return err;
}

}  // namespace

void Hdf5Writer::Impl::reserve(hsize_t bytes, const std::string& where) {
    std::string message;
    if (d.rank() == 0 && can_reserve) {
        // A running bound, not a query (the MPI-IO driver forgets its EOF after a write):
        // HDF5's end of allocation grows by at most bytes + kMetadataSlack per call.
        const hsize_t end = reserved + bytes + kMetadataSlack;
        const int err = allocate_blocks(tmp_path, reserved, end);
        if (err == 0)
            reserved = end;
        else if (err == EOPNOTSUPP)
            can_reserve = false;
        else
            message = "cannot write " + where + ": " + std::strerror(err);
    }
    check_collective(d.comm(), message.empty(), message);
}

Hdf5Writer::Hdf5Writer(const Decomposition& d, const Grid& grid, std::string path,
                       OutputFiles& files)
    : impl_(nullptr), path_(std::move(path)) {
    open(d, grid, files);
}

Hdf5Writer::Hdf5Writer(const Decomposition& d, const Grid& grid, std::string path)
    : own_files_(std::make_unique<OutputFiles>(d.comm())), impl_(nullptr), path_(std::move(path)) {
    open(d, grid, *own_files_);
}

void Hdf5Writer::open(const Decomposition& d, const Grid& grid, OutputFiles& files) {
    MPI_Comm comm = d.comm();
    const bool ok = d.rank() != 0 || folder_writable(folder_of(path_));
    check_collective(comm, ok, cannot_write(path_));
    check_collective(comm, grid.n == d.global().hi && d.global().lo == Int3{0, 0, 0},
                     "cannot write output file '" + path_ +
                         "': the grid does not match the decomposition");

    auto impl = std::make_unique<Impl>(d, grid);
    impl->tmp_path = files.add(path_);
    impl->xdmf_path = xdmf_path_for(path_);
    impl->xdmf_tmp_path = files.add(impl->xdmf_path);
    {
        h5::QuietErrors quiet;
        h5::Handle fapl = h5::plist_handle(H5Pcreate(H5P_FILE_ACCESS));
        // Without the MPI-IO driver every rank would create the file on its own.
        check_collective(comm, H5Pset_fapl_mpio(fapl.get(), comm, MPI_INFO_NULL) >= 0, h5::kNoMpioDriver);
        impl->file = h5::file_handle(
            H5Fcreate(impl->tmp_path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()));
    }
    check_collective(comm, impl->file.valid(), cannot_write(path_));
    impl->reserve(0, "output file '" + path_ + "'");  // throws: impl closes the file
    impl_ = std::move(impl);
}

Hdf5Writer::~Hdf5Writer() {
    if (impl_ != nullptr && !impl_->closed) {
        h5::QuietErrors quiet;
        impl_->file.reset();  // collective MPI_File_close inside
    }
}

const std::string& Hdf5Writer::temporary_path() const { return impl_->tmp_path; }

void Hdf5Writer::write_field(const std::string& name, const Field<double>& f,
                             const std::string& units, const std::string& description) {
    Impl& w = *impl_;
    MPI_Comm comm = w.d.comm();
    const std::string where = "output file '" + path_ + "', field '" + name + "'";
    if (w.closed) throw Error(where + ": the file is already closed");
    if (!valid_field_name(name)) throw Error(where + ": invalid field name");
    if (f.ncomp() != 1 && f.ncomp() != 3)
        throw Error(where + ": fields must have 1 or 3 components, not " +
                    std::to_string(f.ncomp()));
    for (const XdmfField& done : w.fields)
        if (done.name == name) throw Error(where + ": written twice");
    check_collective(comm, f.owned() == w.d.local(),
                     where + ": the field's box does not match the decomposition");

    const Int3& n = w.grid.n;
    const Box& b = f.owned();
    const int rank = f.ncomp() == 3 ? 4 : 3;
    const hsize_t global_dims[4] = {hsize_t(n[2]), hsize_t(n[1]), hsize_t(n[0]), 3};
    const hsize_t start[4] = {hsize_t(b.lo[2]), hsize_t(b.lo[1]), hsize_t(b.lo[0]), 0};
    const hsize_t count[4] = {hsize_t(b.size(2)), hsize_t(b.size(1)), hsize_t(b.size(0)), 3};
    w.reserve(hsize_t(n[0]) * hsize_t(n[1]) * hsize_t(n[2]) * hsize_t(f.ncomp()) * sizeof(float),
              where);

    // The float copy is the writer's one allocation of the field's size, at the end of a run
    // when memory is fullest: a rank without the memory says so to all (were it to throw alone,
    // the others would wait in the next collective and the file's collective close would hang).
    std::vector<float> values;
    bool allocated = true;
    try {
        values.resize(static_cast<size_t>(b.cells() * f.ncomp()));
    } catch (const std::bad_alloc&) {
        allocated = false;
    }
    check_collective(comm, allocated,
                     where + ": not enough memory on some rank for the field's float copy; use more ranks or a "
                             "smaller grid");
    f.copy_owned_to(values.data());
    // Nothing non-finite is written: a NaN, an Inf or a value beyond float32's range (a density
    // of 1e300, which a run takes in double) would open in ParaView as a valid field.
    std::int64_t bad = std::count_if(values.begin(), values.end(), [](float v) { return !std::isfinite(v); });
    MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT64_T, MPI_SUM, comm);
    if (bad > 0)
        throw Error(fmt::format("{}: {} value(s) are NaN, Inf or beyond float32's range (±3.4e38); nothing was "
                                "written (check the scene's densities and optical properties)",
                                where, bad));

    bool ok = true;
    {
        h5::QuietErrors quiet;
        h5::Handle file_space = h5::space_handle(H5Screate_simple(rank, global_dims, nullptr));
        h5::Handle lcpl = h5::plist_handle(H5Pcreate(H5P_LINK_CREATE));
        H5Pset_create_intermediate_group(lcpl.get(), 1);
        h5::Handle dcpl = h5::plist_handle(H5Pcreate(H5P_DATASET_CREATE));
        H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER);  // every cell is written below
        const std::string dset_path = "/fields/" + name;
        h5::Handle dset = h5::dataset_handle(H5Dcreate2(w.file.get(), dset_path.c_str(),
                                                        H5T_IEEE_F32LE, file_space.get(),
                                                        lcpl.get(), dcpl.get(), H5P_DEFAULT));
        ok = dset.valid();
        if (ok) {
            h5::Handle mem_space = h5::space_handle(H5Screate_simple(rank, count, nullptr));
            herr_t selected = 0;
            if (b.empty()) {
                selected = std::min(H5Sselect_none(file_space.get()), H5Sselect_none(mem_space.get()));
            } else {
                selected = H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count,
                                               nullptr);
            }
            h5::Handle dxpl = h5::plist_handle(H5Pcreate(H5P_DATASET_XFER));
            const herr_t collective = H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE);
            // Every rank takes part in the (collective) write whatever its own set-up gave.
            ok = H5Dwrite(dset.get(), H5T_NATIVE_FLOAT, mem_space.get(), file_space.get(),
                          dxpl.get(), values.data()) >= 0 && selected >= 0 && collective >= 0;
            ok = h5::write_string_attribute(dset.get(), "units", units) && ok;
            ok = h5::write_string_attribute(dset.get(), "description", description) && ok;
        }
    }
    check_collective(comm, ok, "cannot write " + where);
    w.fields.push_back({name, f.ncomp()});
}

void Hdf5Writer::write_string_attribute(const std::string& group, const std::string& key,
                                        const std::string& value) {
    Impl& w = *impl_;
    const std::string where =
        "output file '" + path_ + "', attribute '" + key + "' of '" + group + "'";
    if (w.closed) throw Error(where + ": the file is already closed");
    if (key.empty()) throw Error(where + ": empty attribute name");
    // Attribute writes are collective: every rank must pass the same value. A mismatch is a
    // caller bug that would silently corrupt the attribute, so refuse it.
    const unsigned long long h = std::hash<std::string>{}(value), hv[2] = {h, ~h};
    unsigned long long hmax[2];
    MPI_Allreduce(hv, hmax, 2, MPI_UNSIGNED_LONG_LONG, MPI_MAX, w.d.comm());
    if (hmax[0] != h || hmax[1] != ~h)
        throw Error(where + ": the value differs between ranks (attributes are collective)");
    w.reserve(value.size(), where);
    bool ok = false;
    {
        h5::Handle g = h5::open_or_create_group(w.file.get(), group);
        ok = g.valid() && h5::write_string_attribute(g.get(), key, value);
    }
    check_collective(w.d.comm(), ok, "cannot write " + where);
}

void Hdf5Writer::close() {
    Impl& w = *impl_;
    MPI_Comm comm = w.d.comm();
    if (w.closed) throw Error("output file '" + path_ + "' is already closed");
    herr_t closed = 0;
    {
        h5::QuietErrors quiet;
        closed = w.file.reset();
    }
    w.closed = true;  // the destructor has nothing left to close
    check_collective(comm, closed >= 0, "cannot close output file '" + path_ + "'");

    std::string message;
    if (w.d.rank() == 0) {
        std::ofstream out(w.xdmf_tmp_path, std::ios::binary | std::ios::trunc);
        out << xdmf_document(w.grid, fs::path(path_).filename().string(), w.fields);
        out.close();
        if (!out) message = "cannot write XDMF sidecar '" + w.xdmf_path + "'";
    }
    check_collective(comm, message.empty(), message);
}

void Hdf5Writer::commit() {
    if (!own_files_)
        throw Error("output file '" + path_ + "' is committed with its run's other outputs");
    close();
    own_files_->commit();
}

}  // namespace nimbus
