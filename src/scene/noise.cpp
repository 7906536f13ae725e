#include "src/scene/noise.h"

#include <cmath>
#include <numeric>
#include <random>

namespace nimbus {
namespace {
double fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }
double lerp(double t, double a, double b) { return a + t * (b - a); }
double grad(int h, double x, double y, double z) {
    h &= 15;
    const double u = h < 8 ? x : y, v = h < 4 ? y : (h == 12 || h == 14 ? x : z);
    return ((h & 1) ? -u : u) + ((h & 2) ? -v : v);
}
}  // namespace

Noise3::Noise3(unsigned seed) {
    int p[256];
    std::iota(p, p + 256, 0);
    std::mt19937 rng(seed);
    for (int i = 255; i > 0; --i) std::swap(p[i], p[rng() % static_cast<unsigned>(i + 1)]);
    for (int i = 0; i < 512; ++i) perm_[i] = p[i & 255];
}

double Noise3::operator()(double x, double y, double z) const {
    const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    const int X = static_cast<int>(fx) & 255, Y = static_cast<int>(fy) & 255, Z = static_cast<int>(fz) & 255;
    x -= fx; y -= fy; z -= fz;
    const double u = fade(x), v = fade(y), w = fade(z);
    const int* p = perm_;
    const int A = p[X] + Y, AA = p[A] + Z, AB = p[A + 1] + Z;
    const int B = p[X + 1] + Y, BA = p[B] + Z, BB = p[B + 1] + Z;
    return lerp(w,
                lerp(v, lerp(u, grad(p[AA], x, y, z), grad(p[BA], x - 1, y, z)),
                     lerp(u, grad(p[AB], x, y - 1, z), grad(p[BB], x - 1, y - 1, z))),
                lerp(v, lerp(u, grad(p[AA + 1], x, y, z - 1), grad(p[BA + 1], x - 1, y, z - 1)),
                     lerp(u, grad(p[AB + 1], x, y - 1, z - 1), grad(p[BB + 1], x - 1, y - 1, z - 1))));
}

double Noise3::fractal(double x, double y, double z, int octaves) const {
    double sum = 0, amp = 1, freq = 1;
    for (int o = 0; o < octaves; ++o, amp *= 0.5, freq *= 2.0) sum += amp * (*this)(x * freq, y * freq, z * freq);
    return sum;
}

}  // namespace nimbus
