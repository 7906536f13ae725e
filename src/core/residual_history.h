// An iteration's history as one line for an error message: "iteration: value" pairs, and beyond
// 12 entries the first and the last six around "...", so that a solve stopped at a limit of 200
// iterations still gives a readable one-line error.
#pragma once

#include <fmt/format.h>

#include <string>
#include <utility>
#include <vector>

namespace nimbus {

inline std::string format_history(const std::vector<std::pair<int, double>>& history) {
    constexpr size_t kShown = 12;
    std::string s;
    const size_t n = history.size();
    for (size_t i = 0; i < n; ++i) {
        if (n > kShown && i == kShown / 2) {
            s += "..., ";
            i = n - kShown / 2;
        }
        s +=
            fmt::format("{}: {:.3e}{}", history[i].first, history[i].second, i + 1 < n ? ", " : "");
    }
    return s;
}

// The same for a history numbered from iteration 1.
inline std::string format_history(const std::vector<double>& history) {
    std::vector<std::pair<int, double>> numbered;
    numbered.reserve(history.size());
    for (size_t i = 0; i < history.size(); ++i)
        numbered.emplace_back(static_cast<int>(i + 1), history[i]);
    return format_history(numbered);
}

}  // namespace nimbus
