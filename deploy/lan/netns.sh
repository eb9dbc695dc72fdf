# shellcheck shell=bash
# A LAN in network namespaces, sourced by lan.sh and goodput.sh: a switch namespace holding a
# bridge, one namespace per host on it with eth0 at 10.77.0.K/24 (K = 1, 2, ... in the order
# given), or with netns_ipv6=1 at fd77::K/64 alone (an IPv6-only LAN), so the host's own
# network is never touched.
#
#   netns_require NAME              exit 77 (skipped) unless root with `ip netns`
#   netns_up PREFIX SWITCH HOST...  make the switch and the hosts; PREFIX is in every name made
#                                   (e.g. afr$$), so netns_down removes exactly these
#   netns_stop PID...               SIGTERM, then after 0.3 s SIGKILL, to the processes started
#                                   (children of the calling shell), and wait for them
#   netns_hosts HOST LINE...        the host's own /etc/hosts (`ip netns exec` mounts
#                                   /etc/netns/HOST/hosts over it): names on this LAN
#   netns_down SWITCH HOST...       delete the namespaces (and with them the links) and their
#                                   /etc/netns files
#
# Links, read by netns_up: netns_rate (tc syntax, 100mbit; empty: unlimited) puts a tbf with
# netns_burst (256kb) and netns_latency (20ms) on each host's uplink and on the switch's port
# towards it, so both directions of every link are limited; netns_drop (percent, steps of 0.1;
# empty: none) makes nft drop that share of the packets each host sends, at random.
netns_rate="" netns_burst=256kb netns_latency=20ms netns_drop="" netns_ipv6=""
netns_made_etc=""  # whether netns_hosts made /etc/netns (netns_down removes it then only)

netns_require() {
  if [ "$(id -u)" -ne 0 ]; then echo "$1: needs root (network namespaces): skipped"; exit 77; fi
  if ! ip netns list >/dev/null 2>&1; then echo "$1: 'ip netns' unavailable: skipped"; exit 77; fi
}

netns_up() {
  local p=$1 sw=$2 n=0 h permille
  shift 2
  ip netns add "$sw"
  ip -n "$sw" link add br0 type bridge
  ip -n "$sw" link set br0 up
  ip -n "$sw" link set lo up
  for h in "$@"; do
    n=$((n + 1))
    ip netns add "$h"
    ip link add "v$n$p" type veth peer name "eth0$p"
    ip link set "v$n$p" netns "$sw"
    ip link set "eth0$p" netns "$h"
    ip -n "$h" link set "eth0$p" name eth0
    ip -n "$sw" link set "v$n$p" master br0 up
    if [ -n "$netns_ipv6" ]; then
      ip -n "$h" -6 addr add "fd77::$n/64" dev eth0 nodad  # usable at once (no duplicate check)
    else
      ip -n "$h" addr add "10.77.0.$n/24" dev eth0
    fi
    ip -n "$h" link set eth0 up
    ip -n "$h" link set lo up
    if [ -n "$netns_rate" ]; then
      ip netns exec "$h" tc qdisc add dev eth0 root tbf rate "$netns_rate" burst "$netns_burst" \
        latency "$netns_latency"
      ip netns exec "$sw" tc qdisc add dev "v$n$p" root tbf rate "$netns_rate" burst "$netns_burst" \
        latency "$netns_latency"
    fi
    if [ -n "$netns_drop" ]; then
      permille=$(awk -v d="$netns_drop" 'BEGIN { printf "%d", d * 10 }')
      ip netns exec "$h" nft add table inet afr
      ip netns exec "$h" nft add chain inet afr out '{ type filter hook output priority 0; }'
      ip netns exec "$h" nft add rule inet afr out oifname eth0 numgen random mod 1000 lt "$permille" drop
    fi
  done
}

netns_stop() {
  local pid
  for pid in "$@"; do kill -TERM "$pid" 2>/dev/null || true; done
  [ $# -eq 0 ] || sleep 0.3
  for pid in "$@"; do kill -KILL "$pid" 2>/dev/null || true; done
  for pid in "$@"; do wait "$pid" 2>/dev/null || true; done
}

netns_hosts() {
  local h=$1
  shift
  if [ ! -d /etc/netns ]; then
    mkdir /etc/netns
    netns_made_etc=1
  fi
  mkdir -p "/etc/netns/$h"
  printf '%s\n' "$@" >"/etc/netns/$h/hosts"
}

netns_down() {
  local h
  for h in "$@"; do
    ip netns del "$h" 2>/dev/null || true
    rm -rf "/etc/netns/${h:?}"
  done
  if [ -n "$netns_made_etc" ]; then rmdir /etc/netns 2>/dev/null || true; fi
}
