// The display's metrics over HTTP (cpp-httplib), on its own thread.
#pragma once

#include <afr/display/service/metrics.h>

#include <memory>
#include <string>

namespace afr::service {

// Serves a ServiceMetrics over HTTP: /metrics (Prometheus text) and /stats (JSON), on its own
// thread from start() to stop() (or destruction).
class MetricsServer {
 public:
  // Binds now; throws afr::Error naming the address when it cannot.
  MetricsServer(const ServiceMetrics& metrics, const std::string& address, int port);
  ~MetricsServer();
  MetricsServer(const MetricsServer&) = delete;
  MetricsServer& operator=(const MetricsServer&) = delete;
  void start();
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr::service
