// Deterministic 3-D gradient noise (Perlin 2002 "improved noise") and its fractal sum, used
// for the edges of the procedural cumulus (Max 1995 §2 adds Perlin noise to ellipsoids).
#pragma once

namespace nimbus {

class Noise3 {
public:
    explicit Noise3(unsigned seed);
    double operator()(double x, double y, double z) const;          // in about [-1, 1]
    double fractal(double x, double y, double z, int octaves) const;  // sum of octaves, /2 per octave

private:
    int perm_[512];
};

}  // namespace nimbus
