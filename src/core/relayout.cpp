#include "src/core/relayout.h"

#include <mpi.h>

#include <algorithm>
#include <cstdint>

#include "src/core/error.h"
#include "src/core/field.h"
#include "src/core/mpi_counts.h"

namespace nimbus {

namespace {

// Offset of cell (i, j, k) in box b's x-fastest array.
std::int64_t offset_in(const Box& b, int i, int j, int k) {
    return (static_cast<std::int64_t>(k - b.lo[2]) * b.size(1) + (j - b.lo[1])) * b.size(0) + (i - b.lo[0]);
}

// Calls fn(j, k) for each x-row of box `part`, in x-fastest order.
template <class Fn>
void for_each_row(const Box& part, Fn&& fn) {
    if (part.empty()) return;
    for (int k = part.lo[2]; k < part.hi[2]; ++k)
        for (int j = part.lo[1]; j < part.hi[1]; ++j) fn(j, k);
}

}  // namespace

std::vector<double> move_cells(const Decomposition& from, std::span<const double> values, const Decomposition& to) {
    const Box& mine = from.local();
    // This rank's answer, reduced: every rank throws or none goes on to the collectives below.
    check_collective(from.comm(), static_cast<std::int64_t>(values.size()) == mine.cells(),
                     "move_cells: the values do not cover this rank's box");
    // (The same answer on every rank, so all throw or none.)
    if (!(from.global() == to.global()) || from.size() != to.size())
        throw Error("move_cells: the two decompositions do not split the same grid over the same ranks");
    const int P = from.size(), me = from.rank();
    const Box& want = to.local();
    std::vector<double> out(static_cast<size_t>(want.cells()));
    // What stays on this rank is copied directly; the rest goes through one MPI_Alltoallv, each
    // piece x fastest within its box (the receiver unpacks the same box in the same order).
    const Box stay = mine.intersect(want);
    for_each_row(stay, [&](int j, int k) {
        std::copy_n(values.begin() + offset_in(mine, stay.lo[0], j, k), stay.size(0),
                    out.begin() + offset_in(want, stay.lo[0], j, k));
    });
    std::vector<Box> send_part(static_cast<size_t>(P)), recv_part(static_cast<size_t>(P));
    std::vector<std::int64_t> scount(static_cast<size_t>(P)), sdispl(static_cast<size_t>(P)),
        rcount(static_cast<size_t>(P)), rdispl(static_cast<size_t>(P));
    std::int64_t sent = 0, received = 0;
    for (int p = 0; p < P; ++p) {
        const auto q = static_cast<size_t>(p);
        if (p != me) send_part[q] = mine.intersect(to.box_of(p)), recv_part[q] = from.box_of(p).intersect(want);
        sdispl[q] = sent, scount[q] = send_part[q].cells(), sent += scount[q];
        rdispl[q] = received, rcount[q] = recv_part[q].cells(), received += rcount[q];
    }
    std::vector<double> send(static_cast<size_t>(sent)), recv(static_cast<size_t>(received));
    for (int p = 0; p < P; ++p) {
        const Box& part = send_part[static_cast<size_t>(p)];
        auto at = send.begin() + sdispl[static_cast<size_t>(p)];
        for_each_row(part, [&](int j, int k) {
            at = std::copy_n(values.begin() + offset_in(mine, part.lo[0], j, k), part.size(0), at);
        });
    }
    const BlockCounts sb(from.comm(), scount, sdispl, MPI_DOUBLE), rb(from.comm(), rcount, rdispl, MPI_DOUBLE);
    MPI_Alltoallv(send.data(), sb.counts(), sb.displs(), sb.type(), recv.data(), rb.counts(), rb.displs(), rb.type(),
                  from.comm());
    for (int p = 0; p < P; ++p) {
        const Box& part = recv_part[static_cast<size_t>(p)];
        auto at = recv.begin() + rdispl[static_cast<size_t>(p)];
        for_each_row(part, [&](int j, int k) {
            std::copy_n(at, part.size(0), out.begin() + offset_in(want, part.lo[0], j, k));
            at += part.size(0);
        });
    }
    return out;
}

}  // namespace nimbus
