// Path-traced camera image (issue 3 item 2), the Monte Carlo reference for the ray caster.
//
// Per pixel sample: a view ray through the pixel (src/render/camera.h; row 0 at the top) is
// followed through the replicated grid with free-path sampling (grid_walk.h); at each
// collision the throughput takes the albedo (implicit capture) and next-event estimation adds
// every light term's single-scattered radiance through a shadow ray,
//   L += beta a E0_l p(w_l · (-d)) exp(-∫ kappa ds toward -w_l),
// then the path continues in an HG-sampled direction (Russian roulette below the roulette
// weight). Volume sources ([[sources]]) add their emission along every flight by track length,
//   L += beta q len,   q = power / 4π in covered cells with density
// (a flight reaches x with probability T(x), so this estimates the integral of q T).
// Bands with equal optics (src/scene/optics_groups.h) share each path: one walk gives every
// band of the group its radiance (their lights, backgrounds and sources differ only as
// factors), so a grey 3-band scene costs one walk per sample, not three, and its noise is the
// same in the three channels (not coloured). A view ray that leaves unscattered sees the background colour; scattered paths that
// leave see nothing (the background is not a light source, as in the forward tracer).
// alpha = 1 - T along the view ray (first band).
//
// Collective over ctx.decomp.comm(): 8 x 8 tiles of pixels go to the ranks in a scrambled order
// (every rank gets a like share of the cloud; path_tracer.cpp); sample s = pixel spp + k of a band
// group draws from the Philox stream keyed by (seed, the group's first band, s), so the image
// is the same for any rank count, bit for bit. Per-pixel standard error of
// the mean over the samples goes to Image::stderr_rgb. Image on rank 0, empty elsewhere.
// Background kind "ground" is not modelled here: it is rendered black (logged).
// Memory per rank: the replicated density (8 B per cell), a 16-byte voxel grid per band group
// and, with volume sources, 4 B per cell and band: less than the forward tracer's replicated
// arrays, which the model checks against max_replicated_memory_gb before (solve() runs first).
#pragma once

#include "src/model/model.h"
#include "src/model/options.h"
#include "src/render/image.h"

namespace nimbus::mc {

Image path_trace_image(const SolveContext& ctx, const MonteCarloOptions& opt);

}  // namespace nimbus::mc
