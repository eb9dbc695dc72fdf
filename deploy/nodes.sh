# shellcheck shell=bash
# Sourced by run-local.sh and run-wall.sh (from the repository root): building the two node
# programs and stopping the nodes a script started.
#
#   build_nodes DIR NAME   configure DIR (Release, Ninja) when it has no build.ninja, then bring
#                          display_node and sampler_node up to date (a no-op when they are);
#                          NAME prefixes the message
#   pids+=(PID)            a node started; cleanup sends each SIGTERM and waits for it to exit

build_nodes() {
  if [ ! -f "$1/build.ninja" ]; then
    echo "$2: configuring $1/"
    cmake -S . -B "$1" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  fi
  cmake --build "$1" --target display_node sampler_node
}

pids=()
cleanup() {
  local p
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
}
