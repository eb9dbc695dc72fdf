// What ServiceMetrics holds, written out: the Prometheus text format (/metrics), JSON
// (/stats, its layout in docs/service.md) and the one-line summary of the display's log and
// window title. Each reads a consistent snapshot (ServiceMetrics' readers).
#pragma once

#include <afr/display/service/metrics.h>

#include <string>

namespace afr::service {

std::string prometheus_text(const ServiceMetrics& metrics);
std::string stats_json(const ServiceMetrics& metrics);
std::string stats_line(const ServiceMetrics& metrics);

}  // namespace afr::service
