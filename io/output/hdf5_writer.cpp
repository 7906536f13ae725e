// Parallel HDF5 writer (see hdf5_writer.h for the file layout).
//
// Life cycle, every step collective over the decomposition's communicator:
//   1. rank 0 checks that the target folder exists and is writable, and tells everyone
//      (so that no rank can be left inside a collective H5Fcreate that failed elsewhere);
//   2. H5Fcreate("<path>.tmp") with the MPI-IO driver;
//   3. write_field: dataset float32 [nz][ny][nx](,3) of the global grid, each rank writes its
//      owned box as a hyperslab with a collective transfer; string attributes units/description;
//   4. commit: H5Fclose, rank 0 renames to <path> and writes the XDMF sidecar, then everyone
//      agrees on success (one allreduce, which also acts as the closing barrier).
// Without commit the destructor closes the file and rank 0 removes "<path>.tmp".
//
// String attributes are scalar variable-length UTF-8 strings: the object header holds only a
// heap reference, the text lives in the global heap, so values far above the 64 KiB compact
// attribute limit (a JSON report, a TOML scene) need no dense attribute storage.
#include "io/output/hdf5_writer.h"

#include <functional>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <system_error>

#include "io/output/hdf5_detail.h"
#include "io/output/xdmf.h"
#include "src/core/error.h"

namespace nimbus {

namespace fs = std::filesystem;

struct Hdf5Writer::Impl {
    Decomposition d;  // a copy: shares (and keeps alive) the communicator
    Grid grid;
    std::string tmp_path;
    h5::Handle file;
    std::vector<XdmfField> fields;  // in write order, for the XDMF sidecar
    bool committed = false;
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

}  // namespace

Hdf5Writer::Hdf5Writer(const Decomposition& d, const Grid& grid, std::string path)
    : impl_(nullptr), path_(std::move(path)) {
    MPI_Comm comm = d.comm();
    const bool ok = d.rank() != 0 || folder_writable(folder_of(path_));
    check_collective(comm, ok, cannot_write(path_));
    check_collective(comm, grid.n == d.global().hi && d.global().lo == Int3{0, 0, 0},
                     "cannot write output file '" + path_ +
                         "': the grid does not match the decomposition");

    auto impl = std::make_unique<Impl>(Impl{d, grid, path_ + ".tmp", {}, {}, false});
    {
        h5::QuietErrors quiet;
        h5::Handle fapl = h5::plist_handle(H5Pcreate(H5P_FILE_ACCESS));
        H5Pset_fapl_mpio(fapl.get(), comm, MPI_INFO_NULL);
        impl->file = h5::file_handle(
            H5Fcreate(impl->tmp_path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()));
    }
    check_collective(comm, impl->file.valid(), cannot_write(path_));
    impl_ = impl.release();
}

Hdf5Writer::~Hdf5Writer() {
    if (impl_ == nullptr) return;
    if (!impl_->committed) {
        {
            h5::QuietErrors quiet;
            impl_->file.reset();  // collective MPI_File_close inside
        }
        if (impl_->d.rank() == 0) {
            std::error_code ec;
            fs::remove(impl_->tmp_path, ec);
        }
    }
    delete impl_;
}

void Hdf5Writer::write_field(const std::string& name, const Field<double>& f,
                             const std::string& units, const std::string& description) {
    Impl& w = *impl_;
    MPI_Comm comm = w.d.comm();
    const std::string where = "output file '" + path_ + "', field '" + name + "'";
    if (w.committed) throw Error(where + ": the file is already committed");
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

    std::vector<float> values;
    values.reserve(static_cast<size_t>(b.cells() * f.ncomp()));
    for (double v : f.owned_values()) values.push_back(static_cast<float>(v));

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
            if (b.empty()) {
                H5Sselect_none(file_space.get());
                H5Sselect_none(mem_space.get());
            } else {
                H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count,
                                    nullptr);
            }
            h5::Handle dxpl = h5::plist_handle(H5Pcreate(H5P_DATASET_XFER));
            H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE);
            ok = H5Dwrite(dset.get(), H5T_NATIVE_FLOAT, mem_space.get(), file_space.get(),
                          dxpl.get(), values.data()) >= 0;
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
    if (w.committed) throw Error(where + ": the file is already committed");
    if (key.empty()) throw Error(where + ": empty attribute name");
    // Attribute writes are collective: every rank must pass the same value. A mismatch is a
    // caller bug that would silently corrupt the attribute, so refuse it.
    const unsigned long long h = std::hash<std::string>{}(value), hv[2] = {h, ~h};
    unsigned long long hmax[2];
    MPI_Allreduce(hv, hmax, 2, MPI_UNSIGNED_LONG_LONG, MPI_MAX, w.d.comm());
    if (hmax[0] != h || hmax[1] != ~h)
        throw Error(where + ": the value differs between ranks (attributes are collective)");
    bool ok = false;
    {
        h5::Handle g = h5::open_or_create_group(w.file.get(), group);
        ok = g.valid() && h5::write_string_attribute(g.get(), key, value);
    }
    check_collective(w.d.comm(), ok, "cannot write " + where);
}

void Hdf5Writer::commit() {
    Impl& w = *impl_;
    MPI_Comm comm = w.d.comm();
    if (w.committed) throw Error("output file '" + path_ + "' is already committed");
    herr_t closed = 0;
    {
        h5::QuietErrors quiet;
        closed = w.file.reset();
    }
    w.committed = true;  // the file is closed: the destructor has nothing left to close
    check_collective(comm, closed >= 0, "cannot close output file '" + path_ + "'");

    std::string message;
    if (w.d.rank() == 0) {
        try {
            std::error_code ec;
            fs::rename(w.tmp_path, path_, ec);
            if (ec) throw Error("cannot rename '" + w.tmp_path + "' to '" + path_ + "': " +
                                ec.message());
            const std::string xdmf = xdmf_path_for(path_);
            const std::string xdmf_tmp = xdmf + ".tmp";
            {
                std::ofstream out(xdmf_tmp, std::ios::binary | std::ios::trunc);
                out << xdmf_document(w.grid, fs::path(path_).filename().string(), w.fields);
                if (!out.flush()) throw Error("cannot write XDMF sidecar '" + xdmf + "'");
            }
            fs::rename(xdmf_tmp, xdmf, ec);
            if (ec) throw Error("cannot write XDMF sidecar '" + xdmf + "': " + ec.message());
        } catch (const std::exception& e) {
            message = e.what();
        }
    }
    check_collective(comm, message.empty(), message);
}

}  // namespace nimbus
