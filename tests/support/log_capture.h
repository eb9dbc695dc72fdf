// Captures what the default spdlog logger writes at info level and above while it lives, for
// tests that check a log line (format "LEVEL message").
#pragma once

#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <string>
#include <vector>

namespace afr::testing {

class LogCapture {
 public:
  LogCapture() : sink_(std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(256)) {
    previous_ = spdlog::default_logger();
    auto logger = std::make_shared<spdlog::logger>("capture", sink_);
    logger->set_level(spdlog::level::info);
    logger->set_pattern("%l %v");
    spdlog::set_default_logger(logger);
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }

  // The captured lines ("info ...", "warning ...") that contain `part`.
  std::vector<std::string> lines_with(const std::string& part) const {
    std::vector<std::string> out;
    for (const std::string& line : sink_->last_formatted()) {
      if (line.find(part) != std::string::npos) out.push_back(line);
    }
    return out;
  }
  size_t count_level(const std::string& level) const {
    size_t n = 0;
    for (const std::string& line : sink_->last_formatted()) n += line.rfind(level + " ", 0) == 0;
    return n;
  }

 private:
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_;
  std::shared_ptr<spdlog::logger> previous_;
};

}  // namespace afr::testing
