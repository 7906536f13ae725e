// Internal helpers shared by the HDF5 writer and reader (not part of the io/ API): path
// walking and variable-length UTF-8 string attributes (h5py reads them as str); the handle and
// the quiet-errors scope are in io/hdf5_handle.h. Not collective by
// themselves; in the parallel writer every rank calls them with the same arguments.
#pragma once

#include <hdf5.h>

#include <string>
#include <vector>

#include "io/hdf5_handle.h"

namespace nimbus::h5 {

// "/a//b/" -> {"a", "b"}.
std::vector<std::string> split_path(const std::string& path);
// Whether every link along path exists below loc and resolves to an object (H5Lexists and
// H5Oexists_by_name, one component at a time: a dangling link counts as missing).
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
