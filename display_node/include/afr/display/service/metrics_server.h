// The display's metrics over HTTP (cpp-httplib), on its own thread.
#pragma once

#include <afr/display/service/metrics.h>

#include <functional>
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
  // POST /snapshot?delay=SECONDS (default 0.5): calls `handler` with the delay and answers its
  // JSON; an afr::Error it throws is answered 409 with its text. Set before start() (the lead
  // display only; elsewhere the path answers 404).
  void on_snapshot(std::function<std::string(double delay)> handler);
  void start();
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr::service
