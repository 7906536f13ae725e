#include "solvers/montecarlo/empty_space.h"

#include <algorithm>

namespace nimbus::mc {

std::vector<std::uint8_t> empty_space_distance(const std::array<int, 3>& n, const std::vector<float>& kappa) {
    const int nx = n[0], ny = n[1], nz = n[2];
    auto at = [&](int i, int j, int k) { return (static_cast<size_t>(k) * ny + j) * nx + i; };
    std::vector<int> D(kappa.size());
    for (size_t c = 0; c < kappa.size(); ++c) D[c] = kappa[c] > 0.0f ? 0 : 1 << 20;
    auto value = [&](int i, int j, int k) {
        if (i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz) return 0;  // outside: non-empty
        return D[at(i, j, k)];
    };
    // Forward pass: neighbours earlier in raster order; backward pass: the mirror set.
    for (int pass = 0; pass < 2; ++pass) {
        const int s = pass == 0 ? -1 : 1;
        const int k0 = pass == 0 ? 0 : nz - 1, k1 = pass == 0 ? nz : -1;
        const int j0 = pass == 0 ? 0 : ny - 1, j1 = pass == 0 ? ny : -1;
        const int i0 = pass == 0 ? 0 : nx - 1, i1 = pass == 0 ? nx : -1;
        for (int k = k0; k != k1; k -= s)
            for (int j = j0; j != j1; j -= s)
                for (int i = i0; i != i1; i -= s) {
                    int& d = D[at(i, j, k)];
                    if (d == 0) continue;
                    int best = d;
                    for (int dj = -1; dj <= 1; ++dj)
                        for (int di = -1; di <= 1; ++di) best = std::min(best, value(i + di, j + dj, k + s) + 1);
                    for (int di = -1; di <= 1; ++di) best = std::min(best, value(i + di, j + s, k) + 1);
                    best = std::min(best, value(i + s, j, k) + 1);
                    d = best;
                }
    }
    std::vector<std::uint8_t> out(D.size());
    for (size_t c = 0; c < D.size(); ++c) out[c] = static_cast<std::uint8_t>(std::min(D[c], 255));
    return out;
}

}  // namespace nimbus::mc
