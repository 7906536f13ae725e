// The forward photon kernel of photon.h, eight paths at a time in the lanes of AVX-512 vectors
// (x86-64-v4). Same paths as trace_photons (trace_light.h) for the default settings: every
// photon draws the same uniforms from its own Philox stream (Philox in lanes) in the same order
// (the entry point as EntrySampler::sample draws it, the first free path, then per collision
// [roulette], mu, phi, tau), the walk makes the same decisions (the unit step and the
// empty-space jump are one step here, with the jump's half-width 0 for a unit step), and the
// tallies, counters and touched-cell list mean the same. Only the rounding differs: -ln(u) is
// a series of its own (about 1 ulp), FMA contraction differs, and lanes add their segments to
// the voxels in another order, so fields agree with the scalar kernel's to round-off (a path
// could part from its scalar twin where a rounding decides a cell crossing, with probability
// ~1e-16 per crossing; tests/verification/montecarlo/lanes_test.cpp checks equal counts).
//
// Why lanes: one path is a chain of dependent steps (a DDA step, the next one's voxel read, the
// collision's turn and the next flight's set-up), ~6 cycles a cell and ~200 a collision of
// latency on one core. Eight independent paths in one vector fill the core instead.
//
// Scheduling: eight lanes walk together, one cell (or one empty-space jump) each per pass. A
// lane whose flight ends (a collision, or leaving the walked box) parks; once kParkedToServe
// lanes are parked (or none walks), the parked lanes are served together, all in lanes: exits
// booked (the domain face the path leaves by), collisions scattered (implicit capture,
// roulette, HG, azimuth, turn, the next free path), the lanes left empty refilled with the next
// photons (a light's photons are started eight at a time, the entry sampler's faces and live
// pixels in lanes, and wait in a store for the lanes that take them; volume sources' photons
// start in scalar code), and the new flights set up. Two groups of eight lanes take passes in turn, so the core
// overlaps their chains; each pass prefetches the cells its lanes reach by a unit step. Photons
// enter the lanes in index order, so a batch gives the same result whichever rank traces it.
//
// Not used (trace_photons instead) for the verification-only settings: the forced first
// collision and the reduced (unscattered) tally. Not collective; no allocation beyond `lit`.
#pragma once

#include <cstdint>
#include <vector>

#include "solvers/montecarlo/trace_light.h"

namespace nimbus::mc {

// Whether this CPU runs the lane kernel (AVX-512 F, CD, DQ, BW and VL: x86-64-v4).
bool lane_kernel_supported();

// trace_photons (trace_light.h) without the forced first collision and the reduced tally, in
// lanes, with its flux tally (`flux`, optional). Requires lane_kernel_supported().
void trace_photons_lanes(const GridView& grid, const PhotonOptics& optics, const LightTerm& term,
                         std::uint64_t seed, std::int64_t lo, std::int64_t hi,
                         std::vector<std::int64_t>& lit, PathTally& out, double* flux = nullptr);

}  // namespace nimbus::mc
