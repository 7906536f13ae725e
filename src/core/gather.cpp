#include "src/core/gather.h"

#include "src/core/mpi_counts.h"

namespace nimbus {

std::vector<double> allgather_global(const Field<double>& f, const Decomposition& d) {
    std::vector<double> mine;
    mine.reserve(static_cast<size_t>(d.local().cells()));
    for_each_cell(d.local(), [&](int i, int j, int k) { mine.push_back(f(i, j, k)); });
    const int size = d.size();
    std::vector<std::int64_t> counts(static_cast<size_t>(size)), displs(static_cast<size_t>(size));
    std::int64_t off = 0;
    for (int r = 0; r < size; ++r) {
        counts[static_cast<size_t>(r)] = d.box_of(r).cells();
        displs[static_cast<size_t>(r)] = off;
        off += counts[static_cast<size_t>(r)];
    }
    std::vector<double> packed(static_cast<size_t>(d.global().cells()));
    // In blocks when a count passes 2^31 (mpi_counts.h): slabs give whole layers.
    allgatherv_doubles(d.comm(), mine, packed.data(), counts, displs);
    // Unpack each rank's box (x fastest within it) into the global C-order array.
    const Int3 n = d.global().hi;
    std::vector<double> global(packed.size());
    for (int r = 0; r < size; ++r) {
        size_t q = static_cast<size_t>(displs[static_cast<size_t>(r)]);
        for_each_cell(d.box_of(r), [&](int i, int j, int k) {
            global[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] = packed[q++];
        });
    }
    return global;
}

}  // namespace nimbus
