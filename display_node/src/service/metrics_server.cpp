#include <afr/display/service/metrics_server.h>

#include <afr/common/error.h>
#include <afr/display/service/metrics_exposition.h>

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <thread>

namespace afr::service {

struct MetricsServer::Impl {
  httplib::Server server;
  std::thread thread;
  std::string address;
  int port = 0;
};

MetricsServer::MetricsServer(const ServiceMetrics& metrics, const std::string& address, int port)
    : impl_(std::make_unique<Impl>()) {
  impl_->address = address;
  impl_->port = port;
  impl_->server.Get("/metrics", [&metrics](const httplib::Request&, httplib::Response& res) {
    res.set_content(prometheus_text(metrics), "text/plain; version=0.0.4");
  });
  impl_->server.Get("/stats", [&metrics](const httplib::Request&, httplib::Response& res) {
    res.set_content(stats_json(metrics), "application/json");
  });
  if (!impl_->server.bind_to_port(address.c_str(), port)) {
    throw Error(fmt::format("cannot serve metrics on {}:{} (port in use?)", address, port));
  }
}

MetricsServer::~MetricsServer() { stop(); }

void MetricsServer::start() {
  if (impl_->thread.joinable()) return;
  impl_->thread = std::thread([this] { impl_->server.listen_after_bind(); });
  spdlog::info("metrics on http://{}:{}/metrics and /stats", impl_->address, impl_->port);
}

void MetricsServer::stop() {
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

}  // namespace afr::service
