// The parallel ray caster (DESIGN §2): each rank integrates the view rays over its own box
// (front to back, trilinear reconstruction, early termination), then the partial images are
// composited in per-pixel visibility order by direct send; rank 0 holds the final image.
#pragma once

#include "src/core/decomposition.h"
#include "src/core/report.h"
#include "src/model/model.h"
#include "src/render/image.h"
#include "src/render/view_source.h"
#include "src/scene/medium.h"
#include "src/scene/scene.h"

namespace nimbus {

struct RenderInputs {
    const Scene& scene;            // camera, background, render options
    const Medium& medium;          // rho with 1 exchanged ghost layer
    const LightTransport& light;   // tau_rho per light, 1 exchanged ghost layer
    const DiffuseSolution& diffuse;  // fluence (+ flux) with 1 exchanged ghost layer
    // Optional view-path-dependent source (view_source.h), owned by the caller; nullptr: none.
    // Only used in render mode `scattering`.
    ViewRaySource* view_source = nullptr;
};

// Collective over d.comm(). Returns the image on rank 0 and an empty Image elsewhere.
// Times its phases into report under "render/...".
Image render_image(const RenderInputs& in, const Decomposition& d, Report& report);

}  // namespace nimbus
