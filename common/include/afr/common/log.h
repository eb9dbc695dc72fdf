// Logging goes through spdlog; this header sets the one format every afr program uses.
#pragma once

#include <spdlog/spdlog.h>

#include <string_view>

namespace afr {

// Sets the process-wide log level ("trace", "debug", "info", "warn", "error", "off") and the
// line format. Throws afr::Error naming the level if it is not one of those.
void init_logging(std::string_view level);

}  // namespace afr
