// Serial reader for nimbus HDF5 outputs: plain H5Fopen with the default (sec2) driver, so it
// works from any single rank of an MPI run as well as from a serial tool. Values are converted
// to double by HDF5 on read.
#include "io/output/hdf5_reader.h"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "io/output/hdf5_detail.h"
#include "src/core/error.h"

namespace nimbus {

namespace {

// The HDF5 superblock signature, at byte 0 or 512, 1024, 2048, ... (a user block before it).
bool has_hdf5_signature(std::ifstream& in) {
    static const char kSignature[8] = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    for (std::streamoff at = 0; at + 8 <= size; at = at == 0 ? 512 : 2 * at) {
        char head[8] = {};
        in.seekg(at);
        if (!in.read(head, 8)) return false;
        if (std::equal(head, head + 8, kSignature)) return true;
    }
    return false;
}

h5::Handle open_file(const std::string& file) {
    h5::QuietErrors quiet;
    h5::Handle f = h5::file_handle(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
    if (f.valid()) return f;
    // Why not, in the user's terms: HDF5's own stack says "unable to open file" for all of these.
    std::error_code ec;
    const std::filesystem::path p(file);
    if (!std::filesystem::exists(p, ec)) throw Error("cannot open HDF5 file '" + file + "': no such file");
    if (std::filesystem::is_directory(p, ec)) throw Error("cannot open HDF5 file '" + file + "': it is a folder");
    std::ifstream in(file, std::ios::binary);
    if (!in) throw Error("cannot open HDF5 file '" + file + "': it cannot be read (permissions?)");
    if (!has_hdf5_signature(in))
        throw Error("cannot open HDF5 file '" + file + "': it is not an HDF5 file (nimbus writes <name>.h5; the "
                    ".xdmf beside it only points into it)");
    throw Error("cannot open HDF5 file '" + file + "': HDF5 refuses it: truncated or damaged, or the file "
                "system does not support HDF5's file locking (then set HDF5_USE_FILE_LOCKING=FALSE)");
}

std::string located(const std::string& file, const std::string& path) {
    return "HDF5 file '" + file + "', '" + path + "'";
}

bool is_dataset(hid_t file, const std::string& path) {
    if (!h5::link_exists(file, path)) return false;
    h5::QuietErrors quiet;
    H5O_info_t info;
    if (H5Oget_info_by_name(file, path.c_str(), &info, H5P_DEFAULT) < 0) return false;
    return info.type == H5O_TYPE_DATASET;
}

}  // namespace

FieldData read_field(const std::string& file, const std::string& path) {
    h5::Handle f = open_file(file);
    if (!is_dataset(f.get(), path)) throw Error(located(file, path) + ": no such dataset");
    h5::QuietErrors quiet;
    h5::Handle dset = h5::dataset_handle(H5Dopen2(f.get(), path.c_str(), H5P_DEFAULT));
    h5::Handle space = h5::space_handle(H5Dget_space(dset.get()));
    const int rank = H5Sget_simple_extent_ndims(space.get());
    hsize_t dims[4] = {0, 0, 0, 0};
    if (rank != 3 && rank != 4) throw Error(located(file, path) + ": not a 3-D field");
    H5Sget_simple_extent_dims(space.get(), dims, nullptr);
    if (rank == 4 && dims[3] != 3)
        throw Error(located(file, path) + ": a 4-D field must have 3 components");

    FieldData out;
    out.shape = {static_cast<int>(dims[2]), static_cast<int>(dims[1]), static_cast<int>(dims[0])};
    out.ncomp = rank == 4 ? 3 : 1;
    out.values.resize(static_cast<size_t>(dims[0] * dims[1] * dims[2]) * out.ncomp);
    if (!out.values.empty() &&
        H5Dread(dset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT,
                out.values.data()) < 0)
        throw Error(located(file, path) + ": cannot read the dataset");
    h5::read_string_attribute(dset.get(), "units", out.units);
    return out;
}

bool has_dataset(const std::string& file, const std::string& path) {
    h5::Handle f = open_file(file);
    return is_dataset(f.get(), path);
}

bool has_link(const std::string& file, const std::string& path) {
    h5::Handle f = open_file(file);
    return h5::link_exists(f.get(), path);
}

std::vector<std::string> list_group(const std::string& file, const std::string& group) {
    h5::Handle f = open_file(file);
    const std::string path = group.empty() ? "/" : group;
    if (path != "/" && !h5::link_exists(f.get(), path))
        throw Error(located(file, path) + ": no such group");
    h5::QuietErrors quiet;
    h5::Handle g = h5::group_handle(H5Gopen2(f.get(), path.c_str(), H5P_DEFAULT));
    if (!g.valid()) throw Error(located(file, path) + ": not a group");
    std::vector<std::string> names;
    auto collect = [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
        static_cast<std::vector<std::string>*>(data)->emplace_back(name);
        return 0;
    };
    if (H5Literate(g.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names) < 0)
        throw Error(located(file, path) + ": cannot list the group");
    return names;
}

std::string read_string_attribute(const std::string& file, const std::string& object,
                                  const std::string& key) {
    h5::Handle f = open_file(file);
    const std::string path = object.empty() ? "/" : object;
    if (path != "/" && !h5::link_exists(f.get(), path))
        throw Error(located(file, path) + ": no such object");
    std::string value;
    {
        h5::QuietErrors quiet;
        h5::Handle obj = h5::object_handle(H5Oopen(f.get(), path.c_str(), H5P_DEFAULT));
        if (!obj.valid() || !h5::read_string_attribute(obj.get(), key, value))
            throw Error(located(file, path) + ": no string attribute '" + key + "'");
    }
    return value;
}

}  // namespace nimbus
