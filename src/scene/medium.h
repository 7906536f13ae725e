// Medium: density rho on the rank's box (+1 ghost layer, halo-exchanged) and the optical
// properties per band. kappa = rho * sigma_t, sigma_s = a * kappa, sigma_a = (1 - a) * kappa.
#pragma once

#include <vector>

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/grid.h"
#include "src/scene/noise.h"
#include "src/scene/scene.h"

namespace nimbus {

struct Medium {
    Grid grid;
    Field<double> rho;               // owned box + 1 ghost layer; ghosts outside the domain are 0
    std::vector<BandOptics> bands;

    int nbands() const { return static_cast<int>(bands.size()); }
    double kappa(int b, int i, int j, int k) const { return rho(i, j, k) * bands[b].sigma_t; }
};

// Density of the procedural kinds (cumulus, box, sphere) at cell (i, j, k) of grid n.
// Pure function of the spec: the same on every rank, independent of the decomposition.
class ProceduralDensity {
public:
    ProceduralDensity(const MediumSpec& spec, const Int3& n);
    double operator()(int i, int j, int k) const;

private:
    double cumulus(double x, double y, double z) const;
    MediumSpec spec_;
    Int3 n_;
    std::vector<Ellipsoid> ellipsoids_;
    Noise3 noise_;
};

// The built-in cumulus: a flat-bottomed heap of ellipsoids, as in Max 1995 Fig. 2.
std::vector<Ellipsoid> default_cumulus();

// Collective. Fills rho on d.local() from the procedural spec and exchanges the halo.
// Imported kinds (hdf5, raw) are filled by io/density_import instead.
void fill_procedural_density(const MediumSpec& spec, const Decomposition& d, Field<double>& rho);

// Collective. Throws Error on every rank if any density value is negative, NaN or inf.
void check_density(const Field<double>& rho, const Decomposition& d);

Grid make_grid(const GridSpec& g);

}  // namespace nimbus
