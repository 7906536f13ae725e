// Where and in which direction the photons of one volume source start (src/scene/emission.h).
//
//   cell:      uniform over the source's covered cells with density > 0 (all emit the same
//              power density, so this is probability ∝ cell power);
//   position:  uniform inside the cell;
//   direction: isotropic, mu = 1 - 2 xi, phi = 2π xi';
//   weight:    each of the N photons of a batch carries power[b] V / N in band b, V = h³ x the
//              number of emitting cells (m³).
// Draws 6 uniforms from the path's stream. Pure; no MPI; the emitter owns its cell list.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "src/core/grid_walk.h"
#include "solvers/montecarlo/philox.h"
#include "solvers/montecarlo/sincos.h"
#include "src/core/box.h"

namespace nimbus::mc {

struct VolumeEmitter {
    std::vector<double> power;        // per band, W/m³
    Box cells;                        // covered box, domain cells
    std::vector<std::uint32_t> live;  // emitting cells: x + nx (y + ny z), relative to cells.lo
    double volume = 0.0;              // m³ of the emitting cells

    // Emitter of a source over the replicated density rho ([z][y][x] over a grid of n cells)
    // with cell edge h (m).
    template <class Rho>
    VolumeEmitter(std::vector<double> power_per_band, const Box& covered, Rho&& rho, double h)
        : power(std::move(power_per_band)), cells(covered) {
        const Int3 m = cells.shape();
        for (int k = 0; k < m[2]; ++k)
            for (int j = 0; j < m[1]; ++j)
                for (int i = 0; i < m[0]; ++i)
                    if (rho(cells.lo[0] + i, cells.lo[1] + j, cells.lo[2] + k) > 0)
                        live.push_back(static_cast<std::uint32_t>(
                            i + m[0] * (j + static_cast<std::int64_t>(m[1]) * k)));
        volume = static_cast<double>(live.size()) * h * h * h;
    }

    // Power of band b over all emitting cells, W.
    double total_power(int b) const { return power[static_cast<size_t>(b)] * volume; }

    // Start state of one photon in the walked grid (grid_walk.h; its origin is the walked box's
    // lowest domain cell).
    [[gnu::always_inline]] void sample(PathRng& rng, const GridView& grid, PathState& s) const {
        const auto nlive = static_cast<std::int64_t>(live.size());
        const std::int64_t pick = std::min(
            static_cast<std::int64_t>(rng.uniform() * static_cast<double>(nlive)), nlive - 1);
        const std::int64_t c = live[static_cast<size_t>(pick)];
        const Int3 m = cells.shape();
        const std::int64_t rel[3] = {c % m[0], (c / m[0]) % m[1],
                                     c / (static_cast<std::int64_t>(m[0]) * m[1])};
        std::array<int, 3> cell{};
        for (int a = 0; a < 3; ++a) {
            cell[static_cast<size_t>(a)] =
                cells.lo[a] + static_cast<int>(rel[a]) - grid.origin[static_cast<size_t>(a)];
            s.frac[static_cast<size_t>(a)] = rng.uniform();
        }
        s.idx = grid.index(cell);
        const double mu = 1.0 - 2.0 * rng.uniform();
        double cos_phi, sin_phi;
        sincos_2pi(rng.uniform(), cos_phi, sin_phi);
        const double sn = std::sqrt(std::max(0.0, 1.0 - mu * mu));
        s.d = Vec3{sn * cos_phi, sn * sin_phi, mu};
    }
};

}  // namespace nimbus::mc
