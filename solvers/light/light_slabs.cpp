#include "solvers/light/light_slabs.h"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "solvers/sweep/chain.h"
#include "src/core/error.h"

namespace nimbus {

double ChainWork::slab_cost(int lo, int hi, double setup) const {
    double c = 0.0;
    for (int k = lo; k < hi; ++k) c += steps[static_cast<size_t>(k)] + setup * starts[static_cast<size_t>(k)];
    return c + setup * entering[static_cast<size_t>(toward_high_z ? lo : hi)];
}

double ChainWork::max_cost(const std::vector<int>& cuts, double setup) const {
    double m = 0.0;
    for (size_t p = 0; p + 1 < cuts.size(); ++p) m = std::max(m, slab_cost(cuts[p], cuts[p + 1], setup));
    return m;
}

double ChainWork::mean_cost(const std::vector<int>& cuts, double setup) const {
    double s = 0.0;
    for (size_t p = 0; p + 1 < cuts.size(); ++p) s += slab_cost(cuts[p], cuts[p + 1], setup);
    return cuts.size() > 1 ? s / static_cast<double>(cuts.size() - 1) : 0.0;
}

int pilot_stride(const Int3& n) { return std::max(std::min(n[0], n[1]) / 8, 1); }

ChainWork sample_chain_work(const Decomposition& d, RayGrid& slab, const std::vector<DirectionalLight>& lights,
                            int stride) {
    const Int3 n = d.global().shape();
    const auto nz = static_cast<size_t>(n[2]);
    ChainWork w;
    w.steps.assign(nz, 0.0);
    w.starts.assign(nz, 0.0);
    w.entering.assign(nz + 1, 0.0);
    if (lights.empty()) return w;
    w.toward_high_z = -lights.front().w.z > 0;
    std::vector<double> entering_diff(nz + 2, 0.0);  // difference array over faces
    const GridView v = slab.voxels.view(slab.periodic);
    const std::int64_t sz = static_cast<std::int64_t>(v.n[0] + 2) * (v.n[1] + 2);
    const double inv_sz = 1.0 / static_cast<double>(sz);
    const Box& own = d.local();
    // Calls fn(i, j, k) for the sampled cells of box b: every stride-th column in x and y.
    auto for_each_sampled = [&](const Box& b, auto&& fn) {
        auto first = [&](int lo) { return (lo + stride - 1) / stride * stride; };
        for (int k = b.lo[2]; k < b.hi[2]; ++k)
            for (int j = first(b.lo[1]); j < b.hi[1]; j += stride)
                for (int i = first(b.lo[0]); i < b.hi[0]; i += stride) fn(i, j, k);
    };
    for (const DirectionalLight& light : lights) {
        const Vec3 b = -normalized(light.w);
        if ((b.z > 0) != w.toward_high_z || b.z == 0)
            throw Error("sample_chain_work: the lights must all come from the same side, none horizontal");
        const int dir = b.z > 0 ? -1 : 1;
        const sweep::ChainLink link = sweep::chain_link(d, dir);
        const double z_entry = b.z > 0 ? own.lo[2] : own.hi[2];
        for (int g = link.position; g < link.length; ++g) {
            const Box cells = d.box_of(sweep::chain_rank(d, dir, g));
            const bool downstream = g > link.position;
            for_each_sampled(cells, [&](int i, int j, int k) {
                PathState s;
                if (!ray_start(slab, b, piece_start(b, i, j, k, downstream, z_entry), s)) return;
                walk_through(
                    v, s, [](std::int64_t, double) {},
                    [&](std::int64_t idx) {
                        // idx / sz without a division per step (exact after the correction).
                        auto q = static_cast<std::int64_t>(static_cast<double>(idx) * inv_sz);
                        q += (q + 1) * sz <= idx ? 1 : 0;
                        q -= q * sz > idx ? 1 : 0;
                        const int layer = std::clamp(static_cast<int>(q) - 1, 0, v.n[2] - 1) + v.origin[2];
                        w.steps[static_cast<size_t>(layer)] += 1.0;
                    });
            });
        }
        // This rank's sampled rays: where they start, and which z faces they cross before they
        // leave through a non-periodic x/y face (geometry only).
        for_each_sampled(own, [&](int i, int j, int k) {
            w.starts[static_cast<size_t>(k)] += 1.0;
            ++w.rays;
            const double pos[3] = {i + 0.5, j + 0.5, k + 0.5};
            double t_side = std::numeric_limits<double>::infinity();
            for (int a = 0; a < 2; ++a)
                if (!d.periodic(a) && b[a] != 0.0)
                    t_side = std::min(t_side, (b[a] > 0 ? n[a] - pos[a] : pos[a]) / std::abs(b[a]));
            // Where it leaves sideways, clamped to just beyond the z range (±inf when it never does).
            const double z_side = std::clamp(pos[2] + t_side * b.z, -1.0, n[2] + 1.0);
            int f0, f1;  // faces crossed, [f0, f1], internal faces 1..nz-1 only
            if (b.z > 0) {
                f0 = k + 1;
                f1 = std::min(n[2] - 1, static_cast<int>(std::ceil(z_side)) - 1);
            } else {
                f1 = k;
                f0 = std::max(1, static_cast<int>(std::floor(z_side)) + 1);
            }
            if (f0 > f1) return;
            entering_diff[static_cast<size_t>(f0)] += 1.0;
            entering_diff[static_cast<size_t>(f1) + 1] -= 1.0;
        });
    }
    double run = 0.0;
    for (size_t f = 0; f <= nz; ++f) w.entering[f] = (run += entering_diff[f]);
    // Integer counts: the sums are exact whatever the order, so every rank gets the same cuts.
    MPI_Allreduce(MPI_IN_PLACE, w.steps.data(), n[2], MPI_DOUBLE, MPI_SUM, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, w.starts.data(), n[2], MPI_DOUBLE, MPI_SUM, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, w.entering.data(), n[2] + 1, MPI_DOUBLE, MPI_SUM, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &w.rays, 1, MPI_INT64_T, MPI_SUM, d.comm());
    return w;
}

namespace {

// ChainWork::slab_cost in O(1) for a light above (rays toward +z), from prefix sums.
struct SlabCosts {
    std::vector<double> prefix;  // prefix[k]: Σ over layers < k of steps + setup · starts
    const std::vector<double>* entering;
    double setup;
    SlabCosts(const ChainWork& w, double s) : prefix(w.steps.size() + 1, 0.0), entering(&w.entering), setup(s) {
        for (size_t k = 0; k < w.steps.size(); ++k) prefix[k + 1] = prefix[k] + w.steps[k] + s * w.starts[k];
    }
    double operator()(int lo, int hi) const {
        return prefix[static_cast<size_t>(hi)] - prefix[static_cast<size_t>(lo)] +
               setup * (*entering)[static_cast<size_t>(lo)];
    }
};

// Greedy slabs from the light (the top: w toward high z) with cost at most `bound`: the cuts
// from the top down, or an empty vector if more than `parts` slabs would be needed.
std::vector<int> greedy_from_top(const SlabCosts& cost, int nz, int parts, double bound) {
    std::vector<int> cuts{nz};
    int hi = nz;
    while (hi > 0) {
        if (static_cast<int>(cuts.size()) > parts) return {};
        if (cost(hi - 1, hi) > bound) return {};
        int lo = hi - 1;
        // The cost grows as lo moves away from the light (each layer adds its steps; the entry
        // face's rays are at most the next face's plus the layer's starts).
        while (lo > 0 && cost(lo - 1, hi) <= bound) --lo;
        cuts.push_back(lo);
        hi = lo;
    }
    return static_cast<int>(cuts.size()) - 1 <= parts ? cuts : std::vector<int>{};
}

}  // namespace

std::vector<int> balanced_cuts(const ChainWork& work, int parts, double setup) {
    const int nz = static_cast<int>(work.steps.size());
    if (parts < 1 || nz < parts) throw Error("balanced_cuts: need 1 <= parts <= z layers");
    // Solve for light above; light below is the mirror image.
    ChainWork w = work;
    if (!w.toward_high_z) {
        std::reverse(w.steps.begin(), w.steps.end());
        std::reverse(w.starts.begin(), w.starts.end());
        std::reverse(w.entering.begin(), w.entering.end());
        w.toward_high_z = true;
    }
    const SlabCosts cost(w, setup);
    double lo = 0.0, hi = cost(0, nz);
    for (int k = 0; k < nz; ++k) lo = std::max(lo, cost(k, k + 1));
    std::vector<int> best = greedy_from_top(cost, nz, parts, lo);
    if (best.empty()) {
        best = greedy_from_top(cost, nz, parts, hi);
        for (int it = 0; it < 200 && hi - lo > 1e-12 * hi; ++it) {
            const double mid = 0.5 * (lo + hi);
            std::vector<int> c = greedy_from_top(cost, nz, parts, mid);
            if (c.empty()) lo = mid; else hi = mid, best = std::move(c);
        }
    }
    std::reverse(best.begin(), best.end());  // z order: 0 ... nz
    // Fewer slabs than parts: split the thickest (splitting never raises a slab's cost).
    while (static_cast<int>(best.size()) - 1 < parts) {
        size_t widest = 0;
        for (size_t p = 0; p + 1 < best.size(); ++p)
            if (best[p + 1] - best[p] > best[widest + 1] - best[widest]) widest = p;
        best.insert(best.begin() + static_cast<std::ptrdiff_t>(widest) + 1, (best[widest] + best[widest + 1]) / 2);
    }
    if (!work.toward_high_z) {
        for (int& c : best) c = nz - c;
        std::reverse(best.begin(), best.end());
    }
    return best;
}

}  // namespace nimbus
