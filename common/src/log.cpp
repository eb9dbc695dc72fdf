#include <afr/common/log.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <string>

namespace afr {

void init_logging(std::string_view level) {
  const auto parsed = spdlog::level::from_str(std::string(level));
  // from_str answers "off" for anything it does not know; only "off" itself means off.
  if (parsed == spdlog::level::off && level != "off") {
    throw Error(
        fmt::format("unknown log level '{}' (use trace, debug, info, warn, error, off)", level));
  }
  spdlog::set_level(parsed);
  spdlog::set_pattern("%H:%M:%S.%e %^%l%$ %v");
}

}  // namespace afr
