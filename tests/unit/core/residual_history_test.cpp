// format_history: an iteration history as one line for an error message.
#include "src/core/residual_history.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace nimbus {
namespace {

TEST(ResidualHistory, ShortHistoriesAreListedWhole) {
    EXPECT_EQ(format_history(std::vector<double>{}), "");
    EXPECT_EQ(format_history(std::vector<double>{0.5, 0.25}), "1: 5.000e-01, 2: 2.500e-01");
    EXPECT_EQ(format_history(std::vector<std::pair<int, double>>{{1, 0.1}, {2, 0.01}, {4, 1e-3}}),
              "1: 1.000e-01, 2: 1.000e-02, 4: 1.000e-03");
}

// 200 iterations (a solve stopped at its limit) give the first and the last six, not 200 entries.
TEST(ResidualHistory, LongHistoriesKeepTheFirstAndLastSix) {
    std::vector<double> h;
    for (int i = 1; i <= 200; ++i) h.push_back(1.0 / i);
    const std::string s = format_history(h);
    EXPECT_EQ(s.rfind("1: 1.000e+00, 2: 5.000e-01, ", 0), 0u) << s;
    EXPECT_NE(s.find("6: 1.667e-01, ..., 195: "), std::string::npos) << s;
    EXPECT_EQ(s.substr(s.size() - 16), ", 200: 5.000e-03") << s;
    EXPECT_EQ(s.find(", 7: "), std::string::npos) << s;
    size_t entries = 0;
    for (size_t p = s.find(": "); p != std::string::npos; p = s.find(": ", p + 1)) ++entries;
    EXPECT_EQ(entries, 12u) << s;
    // Exactly 12 entries are listed whole.
    h.resize(12);
    EXPECT_EQ(format_history(h).find("..."), std::string::npos);
}

}  // namespace
}  // namespace nimbus
