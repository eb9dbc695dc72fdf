# shellcheck shell=bash
# Sourced by run-local.sh and run-wall.sh (from the repository root): building the two node
# programs, watching the nodes a script started and stopping them.
#
#   build_nodes DIR NAME   configure DIR (Release, Ninja) when it has no build.ninja, then bring
#                          display_node and sampler_node up to date (a no-op when they are);
#                          NAME prefixes the message
#   start_node KIND NAME LOG
#                          a node started ($!): display or sampler, its name and log file
#   watch_nodes NAME       wait for the first node started (the display); a node that fails
#                          is told with its reason; returns 1 when one did
#   cleanup                sends each node SIGTERM and waits for it to exit

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

# start_node KIND NAME LOG: records the node just started in the background ($!): KIND is
# display (its exit status says whether it failed) or sampler (it never exits by itself while a
# display runs, so any exit is a failure); NAME and LOG say which node it is and where it logs.
node_kinds=() node_names=() node_logs=()
start_node() {
  pids+=("$!")
  node_kinds+=("$1")
  node_names+=("$2")
  node_logs+=("$3")
}

# node_reason LOG: the line of a node's log that says why it stopped: its last error, else its
# last line (a flag error, say).
node_reason() {
  local r
  r=$(grep -E '^[0-9:.]+ (error|critical) ' "$1" 2>/dev/null | tail -n 1 || true)
  [ -n "$r" ] || r=$(grep -v -e '^[[:space:]]*$' -e '^Run with --help' "$1" 2>/dev/null | tail -n 1 || true)
  echo "${r:-(its log $1 is empty)}"
}

# watch_nodes NAME: waits until the first node (the display, or a wall's lead) exits. A node
# that fails is told on stderr with its reason; when the first one fails, or every sampler has
# exited, the others are stopped. Returns 0 when no node failed, else 1.
watch_nodes() {
  local failed=0 i p rc alive samplers
  local -A exited=()
  while :; do
    alive=0 samplers=0
    for i in "${!pids[@]}"; do
      p=${pids[$i]}
      [ "${node_kinds[$i]}" = sampler ] && samplers=$((samplers + 1))
      [ -n "${exited[$i]:-}" ] && continue
      if kill -0 "$p" 2>/dev/null; then
        [ "${node_kinds[$i]}" = sampler ] && alive=$((alive + 1))
        continue
      fi
      rc=0
      wait "$p" || rc=$?
      exited[$i]=$rc
      if [ "${node_kinds[$i]}" = sampler ] || [ "$rc" != 0 ]; then
        echo "$1: ${node_names[$i]} failed (exit status $rc): $(node_reason "${node_logs[$i]}")" >&2
        failed=1
      fi
    done
    [ -n "${exited[0]:-}" ] && break
    if [ "$samplers" -gt 0 ] && [ "$alive" = 0 ]; then
      echo "$1: every sampler has exited: stopping the display" >&2
      failed=1
      break
    fi
    sleep 0.2
  done
  return "$failed"
}
