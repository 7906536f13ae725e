#include "io/output/hdf5_detail.h"

namespace nimbus::h5 {

std::vector<std::string> split_path(const std::string& path) {
    std::vector<std::string> parts;
    std::string cur;
    for (char c : path) {
        if (c == '/') {
            if (!cur.empty()) parts.push_back(cur);
            cur.clear();
        } else {
            cur.push_back(c);
        }
    }
    if (!cur.empty()) parts.push_back(cur);
    return parts;
}

bool link_exists(hid_t loc, const std::string& path) {
    QuietErrors quiet;
    std::string prefix;
    for (const std::string& part : split_path(path)) {
        prefix += "/" + part;
        if (H5Lexists(loc, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
        if (H5Oexists_by_name(loc, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
    }
    return true;
}

Handle open_or_create_group(hid_t file, const std::string& path) {
    QuietErrors quiet;
    Handle group = group_handle(H5Gopen2(file, "/", H5P_DEFAULT));
    std::string prefix;
    for (const std::string& part : split_path(path)) {
        prefix += "/" + part;
        if (H5Lexists(file, prefix.c_str(), H5P_DEFAULT) > 0)
            group = group_handle(H5Gopen2(file, prefix.c_str(), H5P_DEFAULT));
        else
            group = group_handle(
                H5Gcreate2(file, prefix.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
        if (!group.valid()) return group;
    }
    return group;
}

namespace {

Handle utf8_vlen_string_type() {
    Handle type = type_handle(H5Tcopy(H5T_C_S1));
    H5Tset_size(type.get(), H5T_VARIABLE);
    H5Tset_cset(type.get(), H5T_CSET_UTF8);
    return type;
}

}  // namespace

bool write_string_attribute(hid_t obj, const std::string& key, const std::string& value) {
    QuietErrors quiet;
    if (H5Aexists(obj, key.c_str()) > 0 && H5Adelete(obj, key.c_str()) < 0) return false;
    Handle type = utf8_vlen_string_type();
    Handle space = space_handle(H5Screate(H5S_SCALAR));
    Handle attr = attr_handle(
        H5Acreate2(obj, key.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT));
    if (!attr.valid()) return false;
    const char* text = value.c_str();
    return H5Awrite(attr.get(), type.get(), &text) >= 0;
}

bool read_string_attribute(hid_t obj, const std::string& key, std::string& value) {
    QuietErrors quiet;
    if (H5Aexists(obj, key.c_str()) <= 0) return false;
    Handle attr = attr_handle(H5Aopen(obj, key.c_str(), H5P_DEFAULT));
    if (!attr.valid()) return false;
    Handle file_type = type_handle(H5Aget_type(attr.get()));
    if (H5Tget_class(file_type.get()) != H5T_STRING) return false;
    Handle space = space_handle(H5Aget_space(attr.get()));
    if (H5Sget_simple_extent_npoints(space.get()) != 1) return false;

    if (H5Tis_variable_str(file_type.get()) > 0) {
        Handle mem_type = type_handle(H5Tcopy(file_type.get()));  // same cset as stored
        char* text = nullptr;
        if (H5Aread(attr.get(), mem_type.get(), &text) < 0) return false;
        value = text != nullptr ? text : "";
        H5free_memory(text);
        return true;
    }
    const size_t size = H5Tget_size(file_type.get());
    Handle mem_type = type_handle(H5Tcopy(file_type.get()));
    H5Tset_strpad(mem_type.get(), H5T_STR_NULLPAD);
    std::string buffer(size, '\0');
    if (H5Aread(attr.get(), mem_type.get(), buffer.data()) < 0) return false;
    value = buffer.substr(0, buffer.find('\0'));
    return true;
}

}  // namespace nimbus::h5
