// ViewVolume: what one rank's ray march reads. For a pinhole camera the view direction at a
// point x is fixed, d(x) = normalize(x - camera), so the view source J_b (source_kernel.h) is
// evaluated ONCE per cell centre before marching; the march then only interpolates rho and
// J_b trilinearly (Max 1995 §1: reconstruction between samples).
//
// Layout: float, owned box + 1 ghost layer (the ghosts come from the exchanged inputs), the
// values of a cell interleaved so one trilinear lookup touches 8 short runs of memory:
// [rho, J_0, ..., J_{nb-1}], or in mode scattering with lights (split_lights)
// [rho, Jd_0.., A_0.., ln T_0..] with J_b = Jd_b + A_b T_b: Jd the diffuse in-scatter and the
// sources, A_b = kappa a_b Σ_l E0_l p_l the lights' single scatter without shadows and T_b =
// Σ_l E0_l p_l T_l / Σ_l E0_l p_l <= 1 their mean transmittance, so that J_b is the lights'
// single scatter at every cell centre. The march interpolates ln T, not J: the sun's T falls
// exponentially through a lit cell, and between an empty cell (T = 1, kept next to the
// medium) and a lit surface cell's centre (T = e^{-kappa h / 2} overhead) J interpolated from
// 0 put the centre's dim value at the cloud's surface (a box at kappa h = 1 under an oblique
// sun rendered 0.72 of its constant cells' single scatter, 0.92 with ln T; overhead 0.87 and
// 0.94, RenderScattering.LitSurfaceOfAThickBox). Each band keeps its own T, so a band's image
// does not depend on the other bands (PsfModel.BandImagesDoNotDepend...). With 3 bands the
// groups are [rho, Jd_0..2 | A_0..2, 0 | ln T_0..2, 0], 4 floats each (the march's vector width).
// Occupancy: the owned box split into 8³-cell blocks; a block
// is empty when rho = 0 on all of its cells and a 1-cell apron, so any trilinear sample whose
// nearest cell lies in the block reads only zeros (J = 0 wherever rho = 0) and can be skipped;
// the bounding box of the occupied blocks lets a ray skip the empty margins in one step.
// Not collective (no MPI) except finish_radiance_bound.
#pragma once

#include <cstdint>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/grid.h"
#include "src/render/raycaster.h"

namespace nimbus {

struct ViewVolume {
    static constexpr int kBlockShift = 3;  // 8³-cell occupancy blocks
    Grid grid;
    Box owned;
    int nbands = 1;
    std::vector<double> sigma_t;          // per band, 1/m per unit density
    Field<float> data;                    // [rho, J_0..J_{nb-1}] (or split, above) on owned + 1 ghost
    bool split_lights = false;            // the layout with A and ln T (header comment)
    int a_offset = 0, log_t_offset = 0;   // where A_0 and ln T_0 are in a cell (split_lights)
    Int3 nblocks{0, 0, 0};
    std::vector<std::uint8_t> occupied;   // nblocks x-fastest; 1 = may hold density
    Box occupied_cells;                   // bounding box of the occupied blocks' cells (may be empty)
    // March.h's early-termination bound B_b per band. build_view_volume sets the largest
    // |J_b| / max(kappa_b, 1/L) of this rank's cells (L: the domain's diagonal) and, after the
    // bands, 1 if some J < 0 else 0; finish_radiance_bound turns that into B_b on every rank.
    std::vector<double> radiance_bound;

    int block_index(int i, int j, int k) const {
        return (((k - owned.lo[2]) >> kBlockShift) * nblocks[1] +
                ((j - owned.lo[1]) >> kBlockShift)) * nblocks[0] + ((i - owned.lo[0]) >> kBlockShift);
    }
};

// Builds the view volume for in.scene.render.mode seen from `camera` (world position, metres).
// Expects in.medium.rho, in.light.tau_rho (scattering) and in.diffuse fields on d.local() with
// at least 1 ghost layer; throws Error otherwise. Not collective (the caller makes errors so).
ViewVolume build_view_volume(const RenderInputs& in, const Decomposition& d, const Vec3& camera);

// Collective over d.comm(). March.h's B_b from build_view_volume's per-rank values:
// S_b = the largest of (the ranks' largest cell term + path[b]), the sky's radiance sky[b] and
// ground_bound[b]; B_b = 2 S_b, or 4 S_b when some rank has J < 0, plus S_b with a view-path
// source (march_source.h). path: a_b H_max,b of the view-path source, empty without one.
void finish_radiance_bound(ViewVolume& v, const std::vector<double>& sky, const std::vector<double>& ground_bound,
                           const Decomposition& d, const std::vector<double>& path = {});

// (Re)computes v.nblocks, v.occupied and v.occupied_cells from v.owned and v.data (owned box
// and its ghost layer filled). Not collective.
void build_occupancy(ViewVolume& v);

}  // namespace nimbus
