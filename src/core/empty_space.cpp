#include "src/core/empty_space.h"

#include <algorithm>

namespace nimbus {

std::vector<std::uint8_t> empty_space_distance(const std::array<int, 3>& n, const std::vector<float>& kappa) {
    const int nx = n[0], ny = n[1], nz = n[2];
    // Padded grid: index (i + 1, j + 1, k + 1); the padding layer is 0 (outside: non-empty).
    const std::int64_t px = nx + 2, py = ny + 2, pz = nz + 2;
    const std::int64_t sy = px, sz = px * py;
    std::vector<int> D(static_cast<size_t>(px * py * pz), 0);
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                D[static_cast<size_t>((k + 1) * sz + (j + 1) * sy + i + 1)] =
                    kappa[(static_cast<size_t>(k) * ny + j) * nx + i] > 0.0f ? 0 : 1 << 20;
    // Forward pass: neighbours earlier in raster order; backward pass: the mirror set.
    for (int pass = 0; pass < 2; ++pass) {
        const std::int64_t s = pass == 0 ? -1 : 1;
        // The 13 neighbour offsets of the half mask: 9 in the k + s plane, 3 in row j + s, 1 at i + s.
        std::int64_t off[13];
        int m = 0;
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) off[m++] = s * sz + dj * sy + di;
        for (int di = -1; di <= 1; ++di) off[m++] = s * sy + di;
        off[m++] = s;
        const int k0 = pass == 0 ? 0 : nz - 1, k1 = pass == 0 ? nz : -1;
        const int j0 = pass == 0 ? 0 : ny - 1, j1 = pass == 0 ? ny : -1;
        const int i0 = pass == 0 ? 0 : nx - 1, i1 = pass == 0 ? nx : -1;
        const int step = pass == 0 ? 1 : -1;
        for (int k = k0; k != k1; k += step)
            for (int j = j0; j != j1; j += step)
                for (int i = i0; i != i1; i += step) {
                    const std::int64_t c = (k + 1) * sz + (j + 1) * sy + i + 1;
                    int& d = D[static_cast<size_t>(c)];
                    if (d == 0) continue;
                    int best = d;
                    for (const std::int64_t o : off) best = std::min(best, D[static_cast<size_t>(c + o)] + 1);
                    d = best;
                }
    }
    std::vector<std::uint8_t> out(kappa.size());
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                out[(static_cast<size_t>(k) * ny + j) * nx + i] = static_cast<std::uint8_t>(
                    std::min(D[static_cast<size_t>((k + 1) * sz + (j + 1) * sy + i + 1)], 255));
    return out;
}

VoxelGrid make_voxels(const std::array<int, 3>& n, const std::vector<float>& kappa) {
    const std::vector<std::uint8_t> skip = empty_space_distance(n, kappa);
    VoxelGrid g;
    g.n = n;
    g.domain = n;
    g.voxel.assign(static_cast<size_t>(n[0] + 2) * (n[1] + 2) * (n[2] + 2), Voxel{0.0f, outside_skip});
    const GridView view = g.view({false, false, false});
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i) {
                const size_t c = (static_cast<size_t>(k) * n[1] + j) * n[0] + i;
                g.voxel[static_cast<size_t>(view.index({i, j, k}))] = {kappa[c], skip[c]};
            }
    return g;
}

}  // namespace nimbus
