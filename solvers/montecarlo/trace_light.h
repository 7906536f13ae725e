// The inner loop of the forward Monte Carlo model: the photons of one light term (or volume
// source) in one batch, traced through the walked grid of one optics group (photon.h), their
// diffuse track lengths accumulated in the grid's voxels (grid_walk.h, Voxel::tally).
//
// A path of weight w adds w len s (cells; s = LightTerm::tally_scale) to Voxel::tally of every
// cell it crosses after its first scattering (emitted photons: from their start); the scale lets
// terms of one colour share the accumulators (batch_in_flight.cpp). Each cell whose tally was 0 before is
// appended to `lit`, so the caller can fold the accumulators into its per-band tallies and zero
// them in O(cells touched). With term.empty_cells the diffuse segments in empty cells are tallied
// as well (their fluence; the uncollided flight keeps its empty-space jumps). With `reduced` (verification only), the uncollided track goes to
// reduced[idx] (cells listed in `lit` too; a cell may be listed twice, folding 0 the second time).
// With `flux` (4 doubles per padded cell, [idx][x, y, z, unused]; 32-byte aligned), each
// collision that ends a tallied flight adds (w s / kappa) d there (w the weight before capture,
// d the flight's direction, kappa the cell's Voxel::kappa in 1/cell): the collision estimator of
// the diffuse flux, whose expectation is the track-length sum w len s d (photon.h). Its cells
// are listed in `lit` (the flight's last segment, in that cell, tallied the fluence).
//
// Compiled twice (x86-64-v3 with AVX2/FMA/BMI, and baseline x86-64), chosen at load time by the
// CPU; the two clones round differently where FMA contracts, so a path may differ in its last
// bits between a CPU with AVX2 and one without (any rank count on one machine gives the same
// answer). Not collective; no allocation beyond `lit`.
#pragma once

#include <cstdint>
#include <vector>

#include "solvers/montecarlo/emitter.h"
#include "src/core/grid_walk.h"
#include "solvers/montecarlo/photon.h"

namespace nimbus::mc {

// Where the photons of one term start: a collimated light (entry faces, direction w) or a
// volume source.
struct LightTerm {
    const EntrySampler* entry = nullptr;
    Vec3 w{0, 0, -1};
    const VolumeEmitter* emitter = nullptr;  // when set, entry and w are not used
    std::uint32_t stream = 0;                // Philox stream of the term (its index)
    double tally_scale = 1.0;                // multiplies every tallied track (diffuse and reduced)
    // Diffuse flights tally their segments in empty cells too (MonteCarloOptions::empty_cells),
    // crossing them one by one; the walked grid must then cover the whole domain.
    bool empty_cells = false;
};

// Traces photons [lo, hi) of `term` with seed `seed`; out collects the energy bookkeeping.
void trace_photons(const GridView& grid, const PhotonOptics& optics, const LightTerm& term, std::uint64_t seed,
                   std::int64_t lo, std::int64_t hi, bool forced_first_collision, double* reduced,
                   std::vector<std::int64_t>& lit, PathTally& out, double* flux = nullptr);

}  // namespace nimbus::mc
