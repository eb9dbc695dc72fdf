#!/usr/bin/env bash
# Starts the afr service on real machines over ssh, from a hosts file:
#   # role  ssh-target        [threads]
#   display render@10.0.0.1
#   sampler render@10.0.0.2   8
#   sampler render@10.0.0.3   8
#   wall    render@10.0.0.4   1,0      (a display wall: the follower display for cell 1,0)
# Usage: deploy/lan/ssh-launch.sh HOSTS start|stop|status [--keys DIR] [--port P] [--bin DIR]
#        [--seconds S] [--scene FILE-ON-DISPLAY-HOST] [--wall CxR] [--size WxH] [--fps F]
# The display hosts refresh at --fps (default 60: each display host is a machine of its own).
# With `wall` hosts, give --wall COLUMNSxROWS: the display leads and shows cell 0,0, each wall
# host shows its cell (docs/wall.md).
# The binaries must be at --bin (default /usr/local/bin) on every host. With --keys DIR (made by
# `display_node keygen DIR --samplers N`), the display gets DIR/display.key + samplers.allow and
# sampler i gets DIR/sampler-i.key + display.pub (copied with scp); without, --insecure.
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 1; }
hosts=$1 action=$2; shift 2
keys="" port=7100 bin=/usr/local/bin seconds=0 scene="" wall=1x1 size=256x256 fps=60
while [ $# -gt 0 ]; do
  case "$1" in
    --keys) keys=$2; shift 2 ;;
    --port) port=$2; shift 2 ;;
    --bin) bin=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    --wall) wall=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --fps) fps=$2; shift 2 ;;
    *) echo "ssh-launch: unknown option '$1'" >&2; exit 1 ;;
  esac
done
[ -r "$hosts" ] || { echo "ssh-launch: cannot read hosts file '$hosts'" >&2; exit 1; }
display="" samplers=() walls=()
while read -r role target threads; do
  case "$role" in
    ''|'#'*) continue ;;
    display) display=$target ;;
    sampler) samplers+=("$target ${threads:-1}") ;;
    wall) walls+=("$target ${threads:?ssh-launch: a wall host needs its cell COLUMN,ROW}") ;;
    *) echo "ssh-launch: $hosts: unknown role '$role'" >&2; exit 1 ;;
  esac
done <"$hosts"
[ -n "$display" ] || { echo "ssh-launch: $hosts names no display" >&2; exit 1; }
display_ip=${display#*@}
case "$action" in
  start)
    dsec=(--insecure)
    if [ -n "$keys" ]; then
      ssh "$display" mkdir -p .afr-keys
      scp -q "$keys/display.key" "$keys/samplers.allow" "$display:.afr-keys/"
      dsec=(--keys .afr-keys)
    fi
    ssh "$display" "nohup $bin/display_node $scene --headless --bind tcp://0.0.0.0:$port --size $size --wall $wall --fps $fps --seconds $seconds ${dsec[*]} --metrics-port 9100 --metrics-address 0.0.0.0 --output afr-out >afr-display.log 2>&1 & echo \$! >afr-display.pid; echo display started on $display"
    for w in "${walls[@]}"; do
      read -r target cell <<<"$w"
      wsec=(--insecure)
      if [ -n "$keys" ]; then
        ssh "$target" mkdir -p .afr-keys
        scp -q "$keys/display.key" "$keys/samplers.allow" "$target:.afr-keys/"
        wsec=(--keys .afr-keys)
      fi
      ssh "$target" "nohup $bin/display_node --headless --follow tcp://$display_ip:$port --cell $cell --bind tcp://0.0.0.0:$port --advertise tcp://${target#*@}:$((port + 2)) --fps $fps --seconds $seconds ${wsec[*]} --metrics-port 9100 --metrics-address 0.0.0.0 --output afr-out >afr-display.log 2>&1 & echo \$! >afr-display.pid; echo wall cell $cell started on $target"
    done
    i=0
    for s in "${samplers[@]}"; do
      i=$((i + 1)); read -r target threads <<<"$s"
      ssec=""
      if [ -n "$keys" ]; then
        ssh "$target" mkdir -p .afr-keys
        scp -q "$keys/sampler-$i.key" "$target:.afr-keys/sampler.key"
        scp -q "$keys/display.pub" "$target:.afr-keys/display.pub"
        ssec="--keys .afr-keys"
      fi
      ssh "$target" "nohup $bin/sampler_node --display tcp://$display_ip:$port --threads $threads $ssec >afr-sampler.log 2>&1 & echo \$! >afr-sampler.pid; echo sampler $i started on $target"
    done
    echo "stats: curl http://$display_ip:9100/stats" ;;
  stop)
    for s in "${samplers[@]}"; do read -r target _ <<<"$s"; ssh "$target" 'kill -TERM "$(cat afr-sampler.pid)"' || true; done
    for w in "${walls[@]}"; do read -r target _ <<<"$w"; ssh "$target" 'kill -TERM "$(cat afr-display.pid)"' || true; done
    ssh "$display" 'kill -TERM "$(cat afr-display.pid)"' || true ;;
  status)
    ssh "$display" tail -n 3 afr-display.log ;;
  *) echo "ssh-launch: action must be start, stop or status" >&2; exit 1 ;;
esac
