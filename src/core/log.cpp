#include "src/core/log.h"

#include <spdlog/sinks/stdout_color_sinks.h>

namespace nimbus::log {

void init(int world_rank, const std::string& level, bool all_ranks) {
    auto logger = spdlog::stderr_color_mt("nimbus");
    logger->set_pattern(all_ranks ? fmt::format("[%T.%e] [r{}] [%^%l%$] %v", world_rank)
                                  : std::string("[%T.%e] [%^%l%$] %v"));
    spdlog::set_default_logger(logger);
    auto lvl = spdlog::level::from_str(level);
    spdlog::set_level(world_rank == 0 || all_ranks ? lvl : spdlog::level::err);
}

}  // namespace nimbus::log
