#include "src/render/balance.h"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "src/core/error.h"

namespace nimbus {

std::vector<int> balanced_split(const std::vector<double>& weight, int nparts) {
    const int n = static_cast<int>(weight.size());
    if (nparts < 1 || n < nparts) throw Error("balanced_split: need 1 <= parts <= layers");
    std::vector<double> prefix(static_cast<size_t>(n) + 1, 0.0);
    for (int k = 0; k < n; ++k) prefix[static_cast<size_t>(k) + 1] = prefix[static_cast<size_t>(k)] + weight[static_cast<size_t>(k)];
    const double total = prefix.back();
    std::vector<int> cut(static_cast<size_t>(nparts) + 1, 0);
    cut[static_cast<size_t>(nparts)] = n;
    for (int p = 1; p < nparts; ++p) {
        int c;
        if (!(total > 0.0)) {
            c = static_cast<int>(static_cast<long long>(n) * p / nparts);
        } else {
            // Boundary nearest the target p/P of the work: the first prefix >= target, or the one before.
            const double target = total * p / nparts;
            c = static_cast<int>(std::lower_bound(prefix.begin(), prefix.end(), target) - prefix.begin());
            if (c > 0 && target - prefix[static_cast<size_t>(c) - 1] <= prefix[static_cast<size_t>(c)] - target) --c;
        }
        // At least one layer per part, before and after this cut.
        cut[static_cast<size_t>(p)] = std::clamp(c, cut[static_cast<size_t>(p) - 1] + 1, n - (nparts - p));
    }
    return cut;
}

std::vector<double> march_work_per_layer(const ViewVolume& v, const Camera& camera) {
    std::vector<double> work(static_cast<size_t>(v.owned.size(2)), 0.0);
    const int bs = 1 << ViewVolume::kBlockShift;
    const Grid& g = v.grid;
    for (int bk = 0; bk < v.nblocks[2]; ++bk)
        for (int bj = 0; bj < v.nblocks[1]; ++bj)
            for (int bi = 0; bi < v.nblocks[0]; ++bi) {
                if (!v.occupied[static_cast<size_t>((bk * v.nblocks[1] + bj) * v.nblocks[0] + bi)]) continue;
                const Int3 b{bi, bj, bk};
                Box cells;
                Vec3 centre;
                for (int a = 0; a < 3; ++a) {
                    cells.lo[a] = v.owned.lo[a] + b[a] * bs;
                    cells.hi[a] = std::min(cells.lo[a] + bs, v.owned.hi[a]);
                    centre[a] = g.origin[a] + 0.5 * (cells.lo[a] + cells.hi[a]) * g.h;
                }
                double u, w;
                if (!camera.project(centre, u, w) || u < 0 || u > camera.width() || w < 0 || w > camera.height())
                    continue;
                const Vec3 r = centre - camera.position();
                const double r2 = dot(r, r), cos_theta = dot(r, camera.forward()) / std::sqrt(r2);
                // Samples per cell ∝ 1 / (r² cos³θ) (balance.h), times the cells of one layer.
                const double per_layer = static_cast<double>(cells.size(0)) * cells.size(1) /
                                         (r2 * cos_theta * cos_theta * cos_theta);
                for (int k = cells.lo[2]; k < cells.hi[2]; ++k)
                    work[static_cast<size_t>(k - v.owned.lo[2])] += per_layer;
            }
    return work;
}

namespace {

struct LayerRange {
    int lo = 0, hi = 0;  // [lo, hi)
    int size() const { return std::max(0, hi - lo); }
};

LayerRange intersect(const LayerRange& a, const LayerRange& b) {
    return {std::max(a.lo, b.lo), std::min(a.hi, b.hi)};
}

float* layer_ptr(Field<float>& f, int k) {
    return f.data() + f.index(f.allocated().lo[0], f.allocated().lo[1], k);
}

}  // namespace

// Fixed cost per layer, in units of the mean sample work per layer (measured, balance.h).
constexpr double kLayerOverhead = 1.0;

ViewVolume balance_view_volume(ViewVolume v, const Decomposition& d, const Camera& camera) {
    const int nranks = d.size(), rank = d.rank();
    if (nranks == 1 || !d.is_slab_z()) return v;
    const MPI_Comm comm = d.comm();
    const int nz = d.global().size(2);

    // 1. The global work per layer: every rank contributes its own layers.
    const std::vector<double> local = march_work_per_layer(v, camera);
    std::vector<int> counts(static_cast<size_t>(nranks)), displs(static_cast<size_t>(nranks));
    std::vector<LayerRange> old_owned(static_cast<size_t>(nranks));
    for (int p = 0; p < nranks; ++p) {
        const Box b = d.box_of(p);
        old_owned[static_cast<size_t>(p)] = {b.lo[2], b.hi[2]};
        counts[static_cast<size_t>(p)] = b.size(2);
        displs[static_cast<size_t>(p)] = b.lo[2];
    }
    std::vector<double> work(static_cast<size_t>(nz));
    MPI_Allgatherv(local.data(), static_cast<int>(local.size()), MPI_DOUBLE, work.data(), counts.data(),
                   displs.data(), MPI_DOUBLE, comm);

    // 2. The balanced split (the same on every rank: same input, same pure function). Each
    //    layer also carries the mean per-layer work as a fixed cost: the per-ray set-up and the
    //    empty-block skips do not scale with the samples (balance.h).
    const double mean = std::accumulate(work.begin(), work.end(), 0.0) / nz;
    for (double& w : work) w += kLayerOverhead * mean;
    const std::vector<int> cut = balanced_split(work, nranks);
    bool unchanged = true;
    for (int p = 0; p < nranks; ++p)
        unchanged = unchanged && cut[static_cast<size_t>(p)] == old_owned[static_cast<size_t>(p)].lo;
    if (unchanged) return v;

    // 3. Move layers: rank p needs its new layers plus one ghost layer each side; the in-domain
    //    ones come from their old owner, the out-of-domain ghosts (k = -1, nz) stay on ranks
    //    0 and P-1, which held them before (both old and new boxes touch the domain's faces).
    auto needed = [&](int p) {
        return LayerRange{std::max(cut[static_cast<size_t>(p)] - 1, 0),
                          std::min(cut[static_cast<size_t>(p) + 1] + 1, nz)};
    };
    Box owned = v.owned;
    owned.lo[2] = cut[static_cast<size_t>(rank)];
    owned.hi[2] = cut[static_cast<size_t>(rank) + 1];
    Field<float> data(owned, 1, v.data.ncomp(), 0.0f);
    const std::ptrdiff_t layer_floats = v.data.stride(2);
    MPI_Datatype layer;
    MPI_Type_contiguous(static_cast<int>(layer_floats), MPI_FLOAT, &layer);
    MPI_Type_commit(&layer);
    std::vector<MPI_Request> requests;
    const LayerRange mine = old_owned[static_cast<size_t>(rank)];
    for (int p = 0; p < nranks; ++p) {
        if (p == rank) continue;
        const LayerRange in = intersect(needed(rank), old_owned[static_cast<size_t>(p)]);
        if (in.size() > 0) {
            requests.emplace_back();
            MPI_Irecv(layer_ptr(data, in.lo), in.size(), layer, p, 0, comm, &requests.back());
        }
        const LayerRange out = intersect(needed(p), mine);
        if (out.size() > 0) {
            requests.emplace_back();
            MPI_Isend(layer_ptr(v.data, out.lo), out.size(), layer, p, 0, comm, &requests.back());
        }
    }
    LayerRange keep = intersect(needed(rank), mine);
    if (owned.lo[2] == 0) keep.lo = std::min(keep.lo, -1);  // the ghost layer below the domain
    if (owned.hi[2] == nz) keep.hi = std::max(keep.hi, nz + 1);  // and above it
    if (keep.size() > 0)
        std::copy_n(layer_ptr(v.data, keep.lo), static_cast<std::ptrdiff_t>(keep.size()) * layer_floats,
                    layer_ptr(data, keep.lo));
    MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
    MPI_Type_free(&layer);

    // 4. The balanced volume.
    v.owned = owned;
    v.data = std::move(data);
    build_occupancy(v);
    return v;
}

}  // namespace nimbus
