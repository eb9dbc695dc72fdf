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

uint64_t LogLimiter::due(std::string_view cause, std::chrono::steady_clock::time_point now) {
  auto it = causes_.find(cause);
  if (it == causes_.end()) {
    const std::string key = causes_.size() < max_causes_ ? std::string(cause) : "other";
    it = causes_.try_emplace(key).first;
  }
  Cause& c = it->second;
  ++c.count;
  if (c.logged && now - c.last_line < interval_) return 0;
  c.logged = true;
  c.last_line = now;
  const uint64_t n = c.count;
  c.count = 0;
  return n;
}

std::string LogLimiter::cause_of(std::string_view message) {
  std::string cause;
  for (char ch : message.substr(0, 80)) {
    const bool digit = ch >= '0' && ch <= '9';
    if (!digit)
      cause += ch;
    else if (cause.empty() || cause.back() != '#')
      cause += '#';
  }
  return cause;
}

}  // namespace afr
