#include "src/physics/band_groups.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "src/scene/optics_groups.h"

namespace nimbus {
namespace {

// a = scale * b componentwise (to round-off), b not all zero; sets scale (least squares).
bool proportional(const std::vector<double>& a, const std::vector<double>& b, double& scale) {
    double num = 0.0, den = 0.0;
    for (size_t i = 0; i < a.size(); ++i) num += a[i] * b[i], den += b[i] * b[i];
    if (den == 0.0) return false;
    scale = num / den;
    for (size_t i = 0; i < a.size(); ++i)
        if (std::abs(a[i] - scale * b[i]) > 1e-12 * std::max(std::abs(a[i]), std::abs(b[i]))) return false;
    return true;
}

// One rhs per band; a band proportional (over the terms) to an earlier rhs band shares it, and
// a band dark in every term needs none (its diffuse field is zero).
BandGroup by_band(const OpticsGroup& og, const std::vector<std::vector<double>>& strength) {
    BandGroup g{og.optics, {}, {}};
    for (const int b : og.bands) {
        std::vector<double> e;
        for (const auto& t : strength) e.push_back(t[static_cast<size_t>(b)]);
        BandUse use{b, {}};
        if (std::all_of(e.begin(), e.end(), [](double v) { return v == 0.0; })) {
            g.bands.push_back(use);
            continue;
        }
        for (size_t r = 0; r < g.rhs_weights.size() && use.terms.empty(); ++r) {
            double scale = 1.0;
            if (proportional(e, g.rhs_weights[r], scale)) use.terms.push_back({static_cast<int>(r), scale});
        }
        if (use.terms.empty()) {
            use.terms.push_back({static_cast<int>(g.rhs_weights.size()), 1.0});
            g.rhs_weights.push_back(e);
        }
        g.bands.push_back(use);
    }
    return g;
}

// One rhs per colour class of terms (strengths over the group's bands proportional); terms
// dark in every band of the group drop out.
BandGroup by_colour(const OpticsGroup& og, const std::vector<std::vector<double>>& strength) {
    const size_t nl = strength.size();
    std::vector<std::vector<double>> colour(nl);  // strength of term l over the group's bands
    for (size_t l = 0; l < nl; ++l)
        for (const int b : og.bands) colour[l].push_back(strength[l][static_cast<size_t>(b)]);
    std::vector<int> first;  // first light of each class
    std::vector<std::vector<double>> weights;
    for (size_t l = 0; l < nl; ++l) {
        if (std::all_of(colour[l].begin(), colour[l].end(), [](double v) { return v == 0.0; })) continue;
        size_t c = 0;
        double scale = 1.0;
        while (c < first.size() && !proportional(colour[l], colour[static_cast<size_t>(first[c])], scale)) ++c;
        if (c == first.size()) {
            first.push_back(static_cast<int>(l));
            weights.emplace_back(nl, 0.0);
            scale = 1.0;
        }
        weights[c][l] = scale;  // term l = scale x the class's first term, in every band
    }
    BandGroup g{og.optics, weights, {}};
    for (size_t k = 0; k < og.bands.size(); ++k) {
        BandUse use{og.bands[k], {}};
        for (size_t c = 0; c < first.size(); ++c) {
            const double s = colour[static_cast<size_t>(first[c])][k];
            if (s != 0.0) use.terms.push_back({static_cast<int>(c), s});
        }
        g.bands.push_back(use);
    }
    return g;
}

}  // namespace

std::vector<BandGroup> group_bands(const std::vector<BandOptics>& bands,
                                   const std::vector<std::vector<double>>& strength, bool superpose) {
    std::vector<BandGroup> groups;
    for (const OpticsGroup& og : group_by_optics(bands)) {
        BandGroup g = by_band(og, strength);
        if (superpose) {
            BandGroup c = by_colour(og, strength);
            if (c.rhs_weights.size() < g.rhs_weights.size()) g = std::move(c);
        }
        groups.push_back(std::move(g));
    }
    return groups;
}

std::vector<std::vector<double>> term_strengths(const std::vector<DirectionalLight>& lights,
                                                const std::vector<VolumeSource>& sources, int nbands) {
    std::vector<std::vector<double>> strength;
    for (const DirectionalLight& l : lights) {
        std::vector<double> e;
        for (int b = 0; b < nbands; ++b) e.push_back(band_value(l.E0, b));
        strength.push_back(std::move(e));
    }
    for (const VolumeSource& s : sources) strength.push_back(s.power);  // one value per band (volume_sources)
    return strength;
}

std::vector<std::string> rhs_band_names(const BandGroup& g, size_t rhs, const std::vector<BandOptics>& bands) {
    std::vector<std::string> names;
    for_each_use(g, rhs, [&](int band, double) { names.push_back(bands[static_cast<size_t>(band)].name); });
    return names;
}

std::vector<std::string> term_names(const std::vector<double>& weights, const std::vector<DirectionalLight>& lights,
                                    size_t nsources) {
    std::vector<std::string> names;
    for (size_t t = 0; t < weights.size(); ++t) {
        if (weights[t] == 0.0) continue;
        std::string name = t < lights.size()            ? lights[t].name
                           : t < lights.size() + nsources ? fmt::format("sources[{}]", t - lights.size())
                                                          : std::string("sky");
        if (name.starts_with("sky[")) name = "sky";
        if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(std::move(name));
    }
    return names;
}

}  // namespace nimbus
