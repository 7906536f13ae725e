// Logging: spdlog underneath. Rank 0 speaks by default; --log-all-ranks lets every rank speak
// (prefixed with its rank). Levels: trace, debug, info, warn, error.
#pragma once

#include <spdlog/spdlog.h>

#include <string>

namespace nimbus::log {

// Call once after MPI_Init. level: one of trace/debug/info/warn/error/off.
void init(int world_rank, const std::string& level = "info", bool all_ranks = false);

template <class... Args>
void info(spdlog::format_string_t<Args...> f, Args&&... a) { spdlog::info(f, std::forward<Args>(a)...); }
template <class... Args>
void warn(spdlog::format_string_t<Args...> f, Args&&... a) { spdlog::warn(f, std::forward<Args>(a)...); }
template <class... Args>
void debug(spdlog::format_string_t<Args...> f, Args&&... a) { spdlog::debug(f, std::forward<Args>(a)...); }

}  // namespace nimbus::log
