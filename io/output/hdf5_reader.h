// Serial reading of nimbus HDF5 outputs (for `nimbus compare`, tests and tools).
#pragma once

#include <array>
#include <string>
#include <vector>

namespace nimbus {

struct FieldData {
    std::array<int, 3> shape{0, 0, 0};  // nx, ny, nz
    int ncomp = 1;
    std::vector<double> values;         // [nz][ny][nx][ncomp], x fastest
    std::string units;
};

// Throws Error if the file or dataset is missing. path e.g. "fields/fluence_diffuse/r".
FieldData read_field(const std::string& file, const std::string& path);
bool has_dataset(const std::string& file, const std::string& path);
// Whether the link at path exists (a group or a dataset); throws Error if the file is missing.
bool has_link(const std::string& file, const std::string& path);
// Names of the links directly under a group, e.g. bands under "fields/fluence_diffuse".
std::vector<std::string> list_group(const std::string& file, const std::string& group);
std::string read_string_attribute(const std::string& file, const std::string& object,
                                  const std::string& key);

}  // namespace nimbus
