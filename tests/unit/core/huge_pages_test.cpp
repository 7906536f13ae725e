// HugePageAllocator (src/core/huge_pages.h): 2 MiB-aligned storage usable by std::vector, values
// kept across growth, and nothing shared between allocations.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "src/core/huge_pages.h"

namespace nimbus {
namespace {

TEST(HugePageAllocator, AlignedStorageForVectors) {
    constexpr std::uintptr_t page = std::uintptr_t{2} << 20;
    std::vector<double, HugePageAllocator<double>> a(1000, 1.5), b(3, -2.0);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(a.data()) % page, 0u);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(b.data()) % page, 0u);
    EXPECT_NE(a.data(), b.data());
    for (int i = 0; i < 300000; ++i) a.push_back(i);  // grows past one 2 MiB page: reallocates
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(a.data()) % page, 0u);
    EXPECT_EQ(a.size(), 301000u);
    EXPECT_EQ(a[999], 1.5);
    EXPECT_EQ(a[1000 + 299999], 299999.0);
    EXPECT_EQ(b[2], -2.0);
}

}  // namespace
}  // namespace nimbus
