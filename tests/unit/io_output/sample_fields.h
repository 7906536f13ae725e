// Sample fields for the output tests: every cell holds a known function of its global index,
// so a file written from any decomposition can be checked cell by cell.
#pragma once

#include <string>

#include "io/output/hdf5_writer.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/grid.h"

namespace nimbus::test {

// i + 1000 j + 1e6 k plus a fraction, so float32 rounding is exercised too.
inline double cell_value(int i, int j, int k, int c = 0, double offset = 0.0) {
    return i + 1000.0 * j + 1.0e6 * k + 0.1 * c + 0.3 + offset;
}

inline Grid sample_grid() {
    Grid g;
    g.n = {5, 4, 6};
    g.h = 0.5;
    g.origin = {-1.0, 2.0, 3.25};
    return g;
}

// A field on the rank's box with one ghost layer holding garbage (ghosts must not be written).
inline Field<double> sample_field(const Decomposition& d, int ncomp, double offset) {
    Field<double> f(d.local(), 1, ncomp, -7.0e30);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        for (int c = 0; c < ncomp; ++c) f(i, j, k, c) = cell_value(i, j, k, c, offset);
    });
    return f;
}

// The fields every sample file holds: name, components, value offset, units.
struct SampleSpec {
    const char* name;
    int ncomp;
    double offset;
    const char* units;
};
inline constexpr SampleSpec kSampleFields[] = {
    {"density", 1, 0.0, "1"},
    {"fluence_diffuse/r", 1, 0.5, "W/m^2"},
    {"fluence_diffuse/g", 1, 0.25, "W/m^2"},
    {"flux_diffuse/r", 3, 0.125, "W/m^2"},
};

inline void write_sample_fields(Hdf5Writer& w, const Decomposition& d) {
    for (const SampleSpec& s : kSampleFields)
        w.write_field(s.name, sample_field(d, s.ncomp, s.offset), s.units,
                      std::string("sample field ") + s.name);
}

}  // namespace nimbus::test
