#include <afr/display/service/metrics_server.h>

#include <afr/common/error.h>
#include <afr/display/service/dashboard.h>
#include <afr/display/service/metrics_exposition.h>

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <thread>

namespace afr::service {

namespace {
constexpr size_t kServerThreads = 96;

// HOST:PORT as a URL writes it: an IPv6 address in brackets.
std::string url_authority(const std::string& host, int port) {
  if (host.find(':') != std::string::npos && host.front() != '[') {
    return fmt::format("[{}]:{}", host, port);
  }
  return fmt::format("{}:{}", host, port);
}
}  // namespace

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
  // The dashboard (dashboard.h): its page, the latest image, the history.
  impl_->server.Get("/", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(kDashboardPage, "text/html; charset=utf-8");
  });
  impl_->server.Get("/image.png", [&metrics](const httplib::Request& req, httplib::Response& res) {
    const std::string png = metrics.dashboard().image_png(req.get_param_value("tiling") == "1");
    if (png.empty()) {
      res.status = 503;  // the display makes images once a page asks: ask again shortly
      res.set_header("Retry-After", "1");
      res.set_content("no image yet", "text/plain");
      return;
    }
    res.set_header("Cache-Control", "no-store");
    res.set_content(png, "image/png");
  });
  impl_->server.Get("/history", [&metrics](const httplib::Request& req, httplib::Response& res) {
    double since = -1e30;
    if (req.has_param("since")) {
      try {
        since = std::stod(req.get_param_value("since"));
      } catch (const std::exception&) {
        res.status = 400;
        res.set_content("since: not a number", "text/plain");
        return;
      }
      if (!std::isfinite(since)) since = -1e30;
    }
    res.set_content(metrics.dashboard().history_json(since), "application/json");
  });
  // Slow or idle clients: each connection may wait at most 1 s for the request's next bytes
  // and 2 s to take the answer, and keeps its connection 2 s between requests; the pool has
  // room for 64 such clients hanging on while /metrics still finds a thread at once.
  impl_->server.set_read_timeout(1, 0);
  impl_->server.set_write_timeout(2, 0);
  impl_->server.set_keep_alive_timeout(2);
  impl_->server.new_task_queue = [] { return new httplib::ThreadPool(kServerThreads); };
  if (!impl_->server.bind_to_port(address.c_str(), port)) {
    throw Error(
        fmt::format("cannot serve metrics on {} (port in use?)", url_authority(address, port)));
  }
}

MetricsServer::~MetricsServer() { stop(); }

void MetricsServer::on_snapshot(std::function<std::string(double delay)> handler) {
  impl_->server.Post("/snapshot", [handler = std::move(handler)](const httplib::Request& req,
                                                                 httplib::Response& res) {
    double delay = 0.5;
    if (req.has_param("delay")) {
      try {
        delay = std::stod(req.get_param_value("delay"));
      } catch (const std::exception&) {
        res.status = 400;
        res.set_content("delay: not a number", "text/plain");
        return;
      }
    }
    try {
      res.set_content(handler(delay), "application/json");
    } catch (const Error& e) {
      res.status = 409;
      res.set_content(e.what(), "text/plain");
    }
  });
}

void MetricsServer::start() {
  if (impl_->thread.joinable()) return;
  impl_->thread = std::thread([this] { impl_->server.listen_after_bind(); });
  spdlog::info("metrics on http://{}/metrics and /stats",
               url_authority(impl_->address, impl_->port));
}

void MetricsServer::stop() {
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

}  // namespace afr::service
