// Internal helpers shared by the HDF5 writer and reader (not part of the io/ API):
// an owning hid_t handle, a scope that silences HDF5's error-stack printing, path walking and
// variable-length UTF-8 string attributes (h5py reads them as str). Not collective by
// themselves; in the parallel writer every rank calls them with the same arguments.
#pragma once

#include <hdf5.h>

#include <string>
#include <utility>
#include <vector>

namespace nimbus::h5 {

// Owns one HDF5 identifier and closes it with the matching H5?close function.
class Handle {
public:
    using Closer = herr_t (*)(hid_t);
    Handle() = default;
    Handle(hid_t id, Closer close) : id_(id), close_(close) {}
    ~Handle() { reset(); }
    Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), close_(o.close_) {}
    Handle& operator=(Handle&& o) noexcept {
        if (this != &o) {
            reset();
            id_ = std::exchange(o.id_, H5I_INVALID_HID);
            close_ = o.close_;
        }
        return *this;
    }
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;

    hid_t get() const { return id_; }
    bool valid() const { return id_ >= 0; }
    // Closes now; returns the close status (>= 0 on success, also when nothing was open).
    herr_t reset() {
        herr_t status = 0;
        if (id_ >= 0 && close_ != nullptr) status = close_(id_);
        id_ = H5I_INVALID_HID;
        return status;
    }

private:
    hid_t id_ = H5I_INVALID_HID;
    Closer close_ = nullptr;
};

inline Handle file_handle(hid_t id) { return {id, H5Fclose}; }
inline Handle group_handle(hid_t id) { return {id, H5Gclose}; }
inline Handle dataset_handle(hid_t id) { return {id, H5Dclose}; }
inline Handle space_handle(hid_t id) { return {id, H5Sclose}; }
inline Handle type_handle(hid_t id) { return {id, H5Tclose}; }
inline Handle attr_handle(hid_t id) { return {id, H5Aclose}; }
inline Handle plist_handle(hid_t id) { return {id, H5Pclose}; }
inline Handle object_handle(hid_t id) { return {id, H5Oclose}; }

// While alive, HDF5 does not print its error stack (failures are reported as nimbus::Error).
class QuietErrors {
public:
    QuietErrors() {
        H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
        H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    }
    ~QuietErrors() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }
    QuietErrors(const QuietErrors&) = delete;
    QuietErrors& operator=(const QuietErrors&) = delete;

private:
    H5E_auto2_t func_ = nullptr;
    void* data_ = nullptr;
};

// "/a//b/" -> {"a", "b"}.
std::vector<std::string> split_path(const std::string& path);
// Whether every link along path exists below loc (H5Lexists one component at a time).
bool link_exists(hid_t loc, const std::string& path);
// Opens the group at path, creating it and any missing parents. Empty or "/" is the root.
Handle open_or_create_group(hid_t file, const std::string& path);

// A scalar variable-length UTF-8 string attribute; replaces an existing one of that name.
// Returns false on failure.
bool write_string_attribute(hid_t obj, const std::string& key, const std::string& value);
// Reads a scalar string attribute, variable or fixed length. Returns false if missing or
// not a string.
bool read_string_attribute(hid_t obj, const std::string& key, std::string& value);

}  // namespace nimbus::h5
