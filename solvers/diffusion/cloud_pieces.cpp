#include "solvers/diffusion/cloud_pieces.h"

#include <mpi.h>

#include <algorithm>
#include <climits>
#include <numeric>
#include <unordered_map>
#include <utility>

#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/mpi_counts.h"

namespace nimbus::diffusion {
namespace {

// Union-find over 0..n-1 with the smaller index as the root (so the result does not depend on
// the order of the unions).
struct DisjointSets {
    std::vector<std::int32_t> parent;
    std::int32_t find(std::int32_t a) {
        while (parent[static_cast<size_t>(a)] != a) {
            auto& p = parent[static_cast<size_t>(a)];
            p = parent[static_cast<size_t>(p)];  // path halving
            a = p;
        }
        return a;
    }
    void unite(std::int32_t a, std::int32_t b) {
        a = find(a);
        b = find(b);
        if (a == b) return;
        if (a > b) std::swap(a, b);
        parent[static_cast<size_t>(b)] = a;
    }
};

// The same over global cell labels (any int64), smallest label as the root.
struct LabelSets {
    std::unordered_map<std::int64_t, std::int64_t> parent;
    std::int64_t find(std::int64_t a) {
        for (;;) {
            const auto it = parent.find(a);
            if (it == parent.end() || it->second == a) return a;
            const auto up = parent.find(it->second);
            if (up != parent.end()) it->second = up->second;  // path halving
            a = it->second;
        }
    }
    void unite(std::int64_t a, std::int64_t b) {
        a = find(a);
        b = find(b);
        if (a == b) return;
        if (a > b) std::swap(a, b);
        parent[b] = a;
        parent.emplace(a, a);
    }
};

// MPI_Allgatherv of every rank's values (doubles that hold integers exactly: below 2^53).
std::vector<double> gather_all(MPI_Comm comm, const std::vector<double>& mine) {
    int size = 1;
    MPI_Comm_size(comm, &size);
    std::vector<std::int64_t> counts(static_cast<size_t>(size)), displs(static_cast<size_t>(size), 0);
    const std::int64_t n = static_cast<std::int64_t>(mine.size());
    MPI_Allgather(&n, 1, MPI_INT64_T, counts.data(), 1, MPI_INT64_T, comm);
    std::partial_sum(counts.begin(), counts.end() - 1, displs.begin() + 1);
    std::vector<double> all(static_cast<size_t>(displs.back() + counts.back()));
    allgatherv_doubles(comm, mine, all.data(), counts, displs);
    return all;
}

}  // namespace

CloudPieces find_cloud_pieces(const Decomposition& d, const Field<double>& kappa_tr, const Box& region) {
    const Box box = d.local().intersect(region);
    const Int3 s = box.shape();
    check_collective(d.comm(), box.cells() <= INT32_MAX,
                     "diffusion: a rank's part of the solve region has more than 2^31 cells");
    const auto local_index = [&](int i, int j, int k) {
        return static_cast<std::int32_t>((i - box.lo[0]) + s[0] * ((j - box.lo[1]) + s[1] * (k - box.lo[2])));
    };
    const Box& g = d.global();
    const auto global_label = [&](int i, int j, int k) {  // the cell's global index, x fastest
        const Int3 n = g.shape();
        return (i - g.lo[0]) + n[0] * ((j - g.lo[1]) + std::int64_t{n[1]} * (k - g.lo[2]));
    };

    // 1. The rank's own pieces: full cells joined through faces inside its box. A cell after a
    // full one along x joins it by its parent pointer alone, and a join to the -y (-z)
    // neighbour is skipped when the -x cell and its -y (-z) neighbour are both full: the four
    // are joined already (most cells of a solid cloud).
    DisjointSets local;
    std::vector<std::int32_t>& up = local.parent;
    up.assign(static_cast<size_t>(box.cells()), -1);
    const std::int32_t sy = s[0], sz = s[0] * s[1];
    const auto is_full = [&](std::int32_t n) { return up[static_cast<size_t>(n)] >= 0; };
    for_each_cell(box, [&](int i, int j, int k) {
        if (!(kappa_tr(i, j, k) > 0.0)) return;
        const std::int32_t c = local_index(i, j, k);
        const bool left = i > box.lo[0] && is_full(c - 1);
        up[static_cast<size_t>(c)] = left ? c - 1 : c;
        if (j > box.lo[1] && is_full(c - sy) && !(left && is_full(c - 1 - sy))) local.unite(c, c - sy);
        if (k > box.lo[2] && is_full(c - sz) && !(left && is_full(c - 1 - sz))) local.unite(c, c - sz);
    });
    // Each local piece gets a compact number q, a label (the global index of its first cell,
    // which is its root: roots are the smallest local index, and local and global order agree
    // within the box), bounds and size. The cells in increasing order, where every parent is a
    // smaller index (unions link the larger root under the smaller one, path halving only
    // shortens): each non-root cell's entry becomes its root, and each root's entry -(q + 2).
    struct Extent {
        Box b{{INT_MAX, INT_MAX, INT_MAX}, {INT_MIN, INT_MIN, INT_MIN}};
        std::int64_t cells = 0;
    };
    const auto compact = [&](std::int32_t c) {
        const std::int32_t v = up[static_cast<size_t>(c)];
        return v <= -2 ? -(v + 2) : -(up[static_cast<size_t>(v)] + 2);
    };
    std::vector<std::int64_t> comp_label;
    std::vector<Extent> comp_extent;
    const Box& own = d.local();
    Field<double> label(box, 1, 1, -1.0);
    for_each_cell(box, [&](int i, int j, int k) {
        const std::int32_t c = local_index(i, j, k);
        const std::int32_t p = up[static_cast<size_t>(c)];
        if (p == -1) return;  // empty
        if (p == c) {  // a root: the piece's first cell
            up[static_cast<size_t>(c)] = -(static_cast<std::int32_t>(comp_label.size()) + 2);
            comp_label.push_back(global_label(i, j, k));
            comp_extent.emplace_back();
        } else if (up[static_cast<size_t>(p)] >= 0) {
            up[static_cast<size_t>(c)] = up[static_cast<size_t>(p)];  // p's root
        }
        const std::int32_t q = compact(c);
        Extent& e = comp_extent[static_cast<size_t>(q)];
        const int at[3] = {i, j, k};
        // The label is read only across the faces of the rank's box (step 2).
        if (at[0] == own.lo[0] || at[0] == own.hi[0] - 1 || at[1] == own.lo[1] || at[1] == own.hi[1] - 1 ||
            at[2] == own.lo[2] || at[2] == own.hi[2] - 1)
            label(i, j, k) = static_cast<double>(comp_label[static_cast<size_t>(q)]);
        for (int a = 0; a < 3; ++a) {
            e.b.lo[a] = std::min(e.b.lo[a], at[a]);
            e.b.hi[a] = std::max(e.b.hi[a], at[a] + 1);
        }
        ++e.cells;
    });

    // 2. Joins across rank boundaries and periodic faces: the neighbours' labels in the ghost
    // layer, pairs gathered on every rank and united there.
    exchange_halo(label, d, region);
    std::vector<double> pairs;
    for (int a = 0; a < 3; ++a)
        for (int side : {-1, 1}) {  // the box's layers on the faces of the rank's box
            const int v = side < 0 ? own.lo[a] : own.hi[a] - 1;
            if (box.empty() || v < box.lo[a] || v >= box.hi[a]) continue;
            for_each_cell(box.with_range(a, v, v + 1), [&](int i, int j, int k) {
                const double mine = label(i, j, k);
                if (mine < 0.0) return;
                int nb[3] = {i, j, k};
                nb[a] += side;
                const double other = label(nb[0], nb[1], nb[2]);
                if (other >= 0.0 && other != mine) pairs.insert(pairs.end(), {mine, other});
            });
        }
    const std::vector<double> all_pairs = gather_all(d.comm(), pairs);
    LabelSets joined;
    for (size_t p = 0; p + 1 < all_pairs.size(); p += 2)
        joined.unite(static_cast<std::int64_t>(all_pairs[p]), static_cast<std::int64_t>(all_pairs[p + 1]));

    // 3. Each piece's bounds and size, merged over its local pieces on every rank.
    std::vector<double> records;  // global label, lo, hi, cells
    for (size_t q = 0; q < comp_label.size(); ++q) {
        const Extent& e = comp_extent[q];
        records.push_back(static_cast<double>(joined.find(comp_label[q])));
        for (int a = 0; a < 3; ++a) records.push_back(e.b.lo[a]);
        for (int a = 0; a < 3; ++a) records.push_back(e.b.hi[a]);
        records.push_back(static_cast<double>(e.cells));
    }
    constexpr size_t kRecord = 8;
    const std::vector<double> all = gather_all(d.comm(), records);
    std::unordered_map<std::int64_t, Extent> merged;
    for (size_t r = 0; r + kRecord <= all.size(); r += kRecord) {
        Extent& e = merged[static_cast<std::int64_t>(all[r])];
        for (int a = 0; a < 3; ++a) {
            e.b.lo[a] = std::min(e.b.lo[a], static_cast<int>(all[r + 1 + static_cast<size_t>(a)]));
            e.b.hi[a] = std::max(e.b.hi[a], static_cast<int>(all[r + 4 + static_cast<size_t>(a)]));
        }
        e.cells += static_cast<std::int64_t>(all[r + 7]);
    }
    std::vector<std::int64_t> order;
    for (const auto& entry : merged) order.push_back(entry.first);
    std::sort(order.begin(), order.end());

    CloudPieces out;
    std::unordered_map<std::int64_t, std::int32_t> piece_of;
    for (const std::int64_t l : order) {
        Box b = merged[l].b;
        for (int a = 0; a < 3; ++a)
            if (d.periodic(a)) b = b.with_range(a, g.lo[a], g.hi[a]);
        piece_of[l] = static_cast<std::int32_t>(out.bounds.size());
        out.bounds.push_back(b);
        out.cells.push_back(merged[l].cells);
    }
    std::vector<std::int32_t> comp_piece(comp_label.size());
    for (size_t q = 0; q < comp_label.size(); ++q) comp_piece[q] = piece_of[joined.find(comp_label[q])];
    out.index = Field<std::int32_t>(box, 0, 1, -1);
    for_each_cell(box, [&](int i, int j, int k) {
        const std::int32_t c = local_index(i, j, k);
        if (up[static_cast<size_t>(c)] != -1) out.index(i, j, k) = comp_piece[static_cast<size_t>(compact(c))];
    });
    return out;
}

}  // namespace nimbus::diffusion
