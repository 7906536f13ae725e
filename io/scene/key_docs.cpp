// The meaning of every scene key, grouped by table in the order scene_to_toml writes them.
// The facts come from the code that reads and uses each key: ranges from Scene::validate()
// (src/scene/scene.cpp), the options' validate() (src/model/options.cpp) and the parsers in
// scene_toml.cpp; units from src/scene/scene.h and src/model/options.h; behaviour from the
// medium (src/scene/medium.cpp), the lights (src/physics/lights.cpp), the camera and the ray
// caster (src/render) and the models (solvers/*/README.md). Lengths come in three kinds, and each
// line says which: grid.unit (cell_size, [[sources]] lo/hi), grid fractions (every position and
// size in [medium]) and metres (camera units = "world", model.diffusion.max_transport_length).
// One line each, short: the READMEs hold the longer story.
#include "io/scene/key_docs.h"

#include <algorithm>

namespace nimbus {

const std::vector<KeyDoc>& scene_key_docs() {
    static const std::vector<KeyDoc> docs = {
        {"title", "shown by `nimbus info` and in the run's log"},

        {"grid", "The cell grid: the domain is the box [0, n × cell_size] along x, y, z (z up)."},
        {"grid.n", "cells along x, y, z, each >= 1"},
        {"grid.cell_size", "cell edge length, in grid.unit (> 0; at least 1 nm in metres)"},
        {"grid.unit", "unit of cell_size, [[sources]] lo/hi: m | km | cm | mm | custom"},
        {"grid.unit_scale",
         "metres per unit (> 0); required with unit = \"custom\", refused otherwise"},
        {"grid.process_grid",
         "ranks along x, y, z; 0 = chosen so that the product is the rank count; all 0 = slabs "
         "along z"},
        {"grid.periodic",
         "periodic faces along x, y, z; z only if every light is horizontal (never dom, lpm, psf); "
         "all three only with albedo < 1 where [[sources]] emit"},

        {"medium", "The density rho (dimensionless): kappa = rho × sigma_t of each band."},
        {"medium.kind", "cumulus | box | sphere, or read from medium.file: hdf5 | raw"},
        {"medium.density",
         "scale of rho, >= 0: multiplies every kind (cumulus peak, box or sphere value, file "
         "values)"},
        {"medium.noise_amplitude",
         "cumulus: strength of the fractal noise that roughens the ellipsoids' edges (0 = smooth), "
         ">= 0"},
        {"medium.noise_scale", "cumulus: noise feature size, in grid fractions (> 0)"},
        {"medium.noise_octaves", "cumulus: octaves of the fractal noise, 1..16"},
        {"medium.seed", "cumulus: seed of the noise (the same seed gives the same cloud)"},
        {"medium.box_lo",
         "box: low corner, grid fractions per axis; a cell is inside when lo <= its centre < hi"},
        {"medium.box_hi", "box: high corner, grid fractions per axis; box_lo < box_hi"},
        {"medium.sphere_center", "sphere: centre, grid fractions per axis"},
        {"medium.sphere_radius",
         "sphere: radius, a fraction of each axis's extent (> 0; an ellipsoid on a non-cubic "
         "grid)"},
        {"medium.file",
         "hdf5 | raw: density file (raw: nx·ny·nz float32, little-endian, x fastest); relative to "
         "the scene file's folder, written absolute"},
        {"medium.dataset", "hdf5: name of the dataset, shape [nz][ny][nx], any number type"},
        {"medium.ellipsoid",
         "cumulus, any number: one ellipsoid of the cloud, rho falling smoothly from its centre "
         "to 0 at its surface (Max 1995 §2); none = a built-in heap of six"},
        {"medium.ellipsoid.center", "centre, grid fractions per axis"},
        {"medium.ellipsoid.radii", "semi-axes, grid fractions per axis (> 0)"},
        {"medium.ellipsoid.density",
         "value at the centre (>= 0); the ellipsoids add, capped at 1, times medium.density"},

        {"optics",
         "One table per colour band (at least one; 1 or 3 with an image: gray, or R, G, B in this "
         "order, by name when named r, g, b or red, green, blue); a per-band value elsewhere is one "
         "number for every band or one per band, in this order."},
        {"optics.name",
         "band name: unique, not empty, no '/' or ':', not stderr_<another band's name>; names the "
         "band's HDF5 datasets"},
        {"optics.sigma_t", "extinction per unit density, 1/m (>= 0): kappa = rho × sigma_t"},
        {"optics.albedo", "single-scattering albedo, in [0, 1]"},
        {"optics.g", "Henyey-Greenstein asymmetry in (-1, 1): 0 isotropic, > 0 forward"},

        {"sun", "The sun: a collimated beam."},
        {"sun.enabled", "false: no sun (direction and irradiance are then not used)"},
        {"sun.direction",
         "direction the light travels (z < 0: downward), any non-zero vector; normalized on load"},
        {"sun.irradiance", "W/m² on a plane normal to the beam, per band"},

        {"sky",
         "A uniform sky over the upper hemisphere, as collimated beams from equal solid angles."},
        {"sky.radiance", "W/(m² sr), per band; [] or 0 in every band = no sky"},
        {"sky.directions", "number of sky beams (equal-solid-angle bins), 1..4096; a multiple of 4 "
                           "is symmetric (rings of 4), others a spiral"},

        {"sources",
         "Any number: an axis-aligned box of isotropic volume emission; models dom, diffusion, "
         "lpm and montecarlo only."},
        {"sources.lo",
         "low corner, in grid.unit from the domain's low corner (required); a cell emits when "
         "lo <= its centre < hi and rho > 0"},
        {"sources.hi", "high corner, in grid.unit (required); lo < hi on every axis"},
        {"sources.power",
         "emitted power per unit volume into all directions, W/m³, per band (radiance source "
         "power / 4π)"},

        {"light", "The light pass: the optical depth from every cell to each sun or sky beam."},
        {"light.method",
         "exact: a ray from every cell centre, O(cells x n), a layer's rays summed at once | "
         "sweep: short characteristics, O(cells), slabs along z only, interpolation error under "
         "an oblique light"},

        {"camera", "The pinhole camera of the image."},
        {"camera.position",
         "eye point: fractions of the domain's extent (units = \"domain\") or metres (\"world\"); above "
         "the ground (z > 0) with background.kind = \"ground\""},
        {"camera.look_at", "the point at the image centre, in the units of position"},
        {"camera.up", "the image's up direction; not parallel to look_at - position"},
        {"camera.fov", "vertical field of view, degrees, in (0, 180)"},
        {"camera.resolution", "[width, height] in pixels, each 1..16384"},
        {"camera.units",
         "of position and look_at: domain (fractions of the extent) | world (metres)"},

        {"background", "What a view ray meets behind the medium."},
        {"background.kind",
         "color | ground: a Lambertian plane at z = 0 lit by the sun and sky, drawn by the ray "
         "caster only (black in model.montecarlo's image); it lights no medium"},
        {"background.color", "radiance behind the medium, above any ground, W/(m² sr), per band"},
        {"background.ground_albedo", "ground: Lambertian albedo, in [0, 1]"},
        {"background.ground_color",
         "ground: albedo per band, in [0, 1], replacing ground_albedo; [] = unused"},

        {"render", "The ray caster that makes the image (Max 1995)."},
        {"render.mode",
         "absorption | emission | emission_absorption | single_unshadowed | scattering (single "
         "scatter with shadows + the model's diffuse light)"},
        {"render.step", "longest ray-march step, in cells (× the cell edge), in (0, 4]"},
        {"render.early_termination",
         "stop a view ray once what lies behind can change its pixel by at most this fraction, "
         "in [0, 1); 0 marches every ray to its end"},
        {"render.emission_color",
         "modes emission and emission_absorption: C, the emitted radiance per unit extinction, "
         "W/(m² sr), per band"},
        {"render.exposure", "PNG preview only: value × exposure before sRGB encoding (> 0)"},

        {"model",
         "The multiple-scattering model; of the [model.<name>] tables below, only its own is "
         "used."},
        {"model.name", "single | diffusion | dom | lpm | psf | montecarlo"},

        {"model.montecarlo", "Forward light tracing reference (solvers/montecarlo/README.md)."},
        {"model.montecarlo.photons", "photon paths over all lights and sources, in [1, 1e14]"},
        {"model.montecarlo.time_budget", "seconds of tracing at most (0 = no limit)"},
        {"model.montecarlo.target_rel_error",
         "stop once the total diffuse power's relative standard error is below this; in [0, 1), "
         "0 = off"},
        {"model.montecarlo.seed", "RNG key: the same seed gives the same result on any rank count"},
        {"model.montecarlo.batches",
         "batches for the batch-means standard errors, 2..4096; one per rank and round, so a "
         "multiple of the rank count keeps every rank busy"},
        {"model.montecarlo.roulette_weight",
         "Russian roulette below this weight (survival 1/2), in (0, 1)"},
        {"model.montecarlo.max_replicated_memory_gb",
         "GB (1e9 bytes) per rank the replicated grid may take, else the run stops (> 0)"},
        {"model.montecarlo.image",
         "path-trace the camera image (next-event estimation) instead of ray casting it"},
        {"model.montecarlo.samples_per_pixel", "camera paths per pixel of that image, >= 1"},
        {"model.montecarlo.kernel",
         "auto (AVX-512 lanes where the CPU has them, else scalar) | lanes | scalar; same paths"},
        {"model.montecarlo.flux",
         "also tally the diffuse flux (flux_diffuse, then the ray caster's in-scatter); 10-12% slower, "
         "and at 1e6 photons its noise speckles the image: for references of many photons"},
        {"model.montecarlo.empty_cells",
         "also estimate fluence_diffuse in the empty cells (DESIGN defines it there; without it they "
         "stay 0): about 2x the tracing time on the default cloud"},

        {"model.diffusion", "P1 diffusion on hypre (solvers/diffusion/README.md)."},
        {"model.diffusion.solver",
         "pfmg | smg | pfmg-pcg | smg-pcg (hypre) | petsc (cross-check, slabs along z only)"},
        {"model.diffusion.tolerance", "relative residual of every solve, in (0, 1)"},
        {"model.diffusion.max_iterations", "per solve, >= 1; not converging is an error"},
        {"model.diffusion.margin",
         "cells added around the bounding box of the non-empty cells to make the solve region, "
         ">= 0; cost only, the fields do not depend on it"},
        {"model.diffusion.max_transport_length",
         "metres (whatever grid.unit): cap on 1/kappa_tr in D and G; 0 = half the smallest "
         "non-periodic extent of the bounding box of each piece of cloud (full cells joined by faces)"},
        {"model.diffusion.clamp_negative", "set negative P1 fluence to 0 (the count is reported)"},
        {"model.diffusion.delta_scaling", "delta-Eddington optics and first-scatter source"},
        {"model.diffusion.flux_limiter", "none | levermore-pomraning (flux-limited diffusion)"},
        {"model.diffusion.limiter_iterations",
         "flux-limiter iterations at most, >= 1; only with the limiter"},
        {"model.diffusion.limiter_tolerance",
         "the limiter stops when max |ΔU| / max U is below this, in (0, 1); only with the limiter"},
        {"model.diffusion.petsc_options",
         "solver = \"petsc\" only: PETSc options with the prefix -diffusion_; empty = CG + "
         "BoomerAMG"},

        {"model.dom", "Discrete ordinates (solvers/dom/README.md)."},
        {"model.dom.quadrature",
         "level-symmetric (S_N) | product (Gauss-Legendre polar × Chebyshev azimuths) | cube96 "
         "(Max's 96 cube-face bins)"},
        {"model.dom.order", "level-symmetric: S_N order, even, 2..16"},
        {"model.dom.polar", "product: Gauss-Legendre polar points over [-1, 1], even, >= 2"},
        {"model.dom.azimuthal", "product: Chebyshev azimuths, a multiple of 4"},
        {"model.dom.legendre_order",
         "L: the phase function expanded in Legendre moments 0..L, 0..64 (S_N integrates them to N - 1)"},
        {"model.dom.delta_m", "delta-M scaling of the truncated phase function (Wiscombe 1977)"},
        {"model.dom.scheme", "step | diamond (diamond difference with negative-flux fix-up)"},
        {"model.dom.iteration",
         "source | dsa (hypre) | gmres (DSA-preconditioned, PETSc) | gmres-plain"},
        {"model.dom.tolerance",
         "relative change (source, dsa) or residual (gmres) of the scalar flux, in (0, 1)"},
        {"model.dom.max_iterations", ">= 1; not converging is an error"},
        {"model.dom.tile_rows", "KBA block rows across the slab face (the pipeline's grain), >= 1"},
        {"model.dom.octant_overlap", "octants swept at once: 1 | 2 (+z/-z pairs) | 8"},
        {"model.dom.reflective",
         "specular faces, any of x-, x+, y-, y+, z-, z+; a + face needs iteration source or dsa"},
        {"model.dom.sky",
         "first-collision (the sky as a source) | boundary (its radiance enters at the faces)"},

        {"model.lpm", "Light propagation maps, Fattal 2009 (solvers/lpm/README.md)."},
        {"model.lpm.p", "directions per map: p × p, >= 1 (odd p has horizontal rays)"},
        {"model.lpm.refinement", "map rays per grid cell along each map axis, >= 1"},
        {"model.lpm.k", "6 k² coarse angular bins of the unpropagated light U; k divides p"},
        {"model.lpm.solution_bins", "1 (fluence) | 4 (fluence and flux)"},
        {"model.lpm.iterations", "map sweeps (all six maps) at most, >= 1"},
        {"model.lpm.epsilon", "stop once max U < epsilon × peak first-scatter source, in [0, 1)"},
        {"model.lpm.tail",
         "the light left in U at the stop: none | geometric | diffusion (one P1 solve) | dsa (a P1 "
         "correction fed back after every round, then the P1 tail)"},

        {"model.psf", "Path-integral point-spread function, Premoze 2004 (solvers/psf/README.md)."},
        {"model.psf.levels",
         "light-pyramid levels including level 0; 0 = until the coarsest has <= 2 cells per axis"},
        {"model.psf.step_growth",
         "view-ray sample spacing in blur-sphere diameters (0 = every render step), >= 0"},

        {"output", "The files <dir>/<name>.h5 (with .xdmf), .exr and .png."},
        {"output.dir",
         "output folder, from the working directory (not the scene file's); created if missing; "
         "not empty (\".\" for the working directory)"},
        {"output.name", "file name stem: not empty, no '/' or ':'"},
        {"output.hdf5", "write <name>.h5 (fields, effective scene, run report) and .xdmf"},
        {"output.image", "render and write the image, <name>.exr and its preview <name>.png "
                         "(needs 1 or 3 bands)"},
    };
    return docs;
}

std::string_view scene_key_meaning(std::string_view path) {
    const auto& docs = scene_key_docs();
    const auto it =
        std::find_if(docs.begin(), docs.end(), [&](const KeyDoc& d) { return d.path == path; });
    return it == docs.end() ? std::string_view{} : it->meaning;
}

}  // namespace nimbus
