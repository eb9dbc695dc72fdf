#!/usr/bin/env bash
# deploy/monitoring: Prometheus's configuration and rules pass promtool (Debian's
# `prometheus`; skipped, status 77, without it), the Grafana dashboard is JSON, and every afr_
# metric the rules and the dashboard name is one display_node exposes.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
dir=$root/deploy/monitoring
exposition=$root/display_node/src/service/metrics_exposition.cpp
python3 -c "import json, sys; json.load(open(sys.argv[1]))" "$dir/grafana-dashboard.json"
missing=0
for name in $(grep -oh 'afr_[a-z_]*' "$dir/afr-rules.yml" "$dir/grafana-dashboard.json" | sort -u); do
  base=${name%_bucket}
  if ! grep -q "\"$base" "$exposition"; then
    echo "monitoring: $name is named in deploy/monitoring but display_node does not expose it" >&2
    missing=1
  fi
done
[ "$missing" = 0 ] || exit 1
if ! command -v promtool >/dev/null; then
  echo "monitoring: promtool not installed (Debian package prometheus): config not checked"
  exit 77
fi
promtool check config "$dir/prometheus.yml"
promtool check rules "$dir/afr-rules.yml"
echo "monitoring: config, rules and dashboard check out"
