#!/usr/bin/env bash
# Runs one libFuzzer target for SECONDS over a scratch copy of its seed corpus and prints how
# many inputs it executed and whether it crashed (exit status 1, with the crashing input kept).
#   bench/fuzz.sh TARGET SECONDS [libFuzzer flags...]
# TARGET is protocol, aff, gltf or camera_path (or afr_fuzz_<that>). Extra flags go to
# libFuzzer, e.g. -runs=10000000 to stop after that many executions (SECONDS 0: no time limit).
# Environment:
#   AFR_BUILD_DIR   a clang build with AFR_BUILD_FUZZ=ON (default build-asan, configured with
#                   the asan preset when missing)
#   AFR_FUZZ_BUILD  0: use the binary as it is (ctest); otherwise it is built first
#   AFR_FUZZ_KEEP   1: keep the scratch directory (the corpus grown by the run) after success
#   AFR_FUZZ_CORPUS a corpus directory to run on in place instead of the scratch copy (created
#                   when missing, the seeds added to it): a later run with the same directory
#                   continues from the corpus the earlier ones grew
# docs/robustness.md, "Fuzzing", has the figures of the long runs and how they were made.
set -euo pipefail

if [[ $# -lt 2 ]]; then
  echo "usage: $0 TARGET SECONDS [libFuzzer flags...]" >&2
  exit 2
fi
root="$(cd "$(dirname "$0")/.." && pwd)"
name="${1#afr_fuzz_}"
seconds="$2"
shift 2
target="afr_fuzz_${name}"
seeds="$root/tests/fuzz/corpus/$name"
if [[ ! -d "$seeds" ]]; then
  echo "fuzz.sh: unknown target '$1' (no seed corpus $seeds)" >&2
  exit 2
fi
build="${AFR_BUILD_DIR:-$root/build-asan}"

if [[ "${AFR_FUZZ_BUILD:-1}" != 0 ]]; then
  if [[ ! -f "$build/CMakeCache.txt" ]]; then
    if [[ -n "${AFR_BUILD_DIR:-}" ]]; then
      echo "fuzz.sh: $build is not a configured build directory" >&2
      exit 2
    fi
    (cd "$root" && cmake --preset asan)
  fi
  nice -n 10 cmake --build "$build" --target "$target"
fi
binary="$build/tests/fuzz/$target"
if [[ ! -x "$binary" ]]; then
  echo "fuzz.sh: $binary not found (configure with AFR_BUILD_FUZZ=ON, clang)" >&2
  exit 2
fi

mkdir -p "$build/fuzz-runs"
scratch="$(mktemp -d "$build/fuzz-runs/$name.XXXXXX")"
corpus="${AFR_FUZZ_CORPUS:-$scratch/corpus}"
mkdir -p "$corpus"
cp -n "$seeds"/* "$corpus/"
seed_count=$(find "$corpus" -type f | wc -l)
flags=(-max_total_time="$seconds" -max_len=4096 -rss_limit_mb=2048 -timeout=10
       -print_final_stats=1 -artifact_prefix="$scratch/")
dict="$root/tests/fuzz/$name.dict"
[[ -f "$dict" ]] && flags+=(-dict="$dict")

# Leaks inside uninstrumented libraries afr cannot fix are listed there.
export LSAN_OPTIONS="suppressions=$root/tests/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"

limit="$seconds s"
[[ "$seconds" == 0 ]] && limit="no time limit"
echo "$target: $limit, $seed_count inputs in $corpus, scratch $scratch"
status=0
start=$SECONDS
nice -n 10 "$binary" "${flags[@]}" "$@" "$corpus" >"$scratch/log" 2>&1 || status=$?

final_stat() { sed -n "s/^stat::$1: *//p" "$scratch/log" | tail -1; }
executions="$(final_stat number_of_executed_units)"
rate="$(final_stat average_exec_per_sec)"
elapsed=$((SECONDS - start))
corpus_count=$(find "$corpus" -type f | wc -l)
corpus_kb=$(( $(find "$corpus" -type f -exec cat {} + | wc -c) / 1024 ))
crash="$(find "$scratch" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' \
        -o -name 'oom-*' \) -printf '%f\n')"
# A sanitizer, libFuzzer (out-of-memory, timeout, deadly signal) or AFR_CHECK report; a run
# that was interrupted (Ctrl-C, kill) has none.
report='ERROR: |runtime error|internal check failed|terminate called'
if [[ $status -ne 0 && -z "$crash" ]] && ! grep -q -E "$report" "$scratch/log"; then
  echo "$target: stopped with exit status $status after ${executions:-?} executions" \
       "(log: $scratch/log)"
  exit "$status"
fi
if [[ $status -ne 0 || -n "$crash" ]]; then
  grep -E -A40 "$report" "$scratch/log" | head -80
  echo "$target: CRASHED after ${executions:-?} executions; input: $scratch/${crash:-?}" \
       "(log: $scratch/log)"
  exit 1
fi
echo "$target: ${executions} executions in ${elapsed} s (${rate} per second), no crash;" \
     "corpus $seed_count -> $corpus_count inputs (${corpus_kb} KB)"
if [[ "${AFR_FUZZ_KEEP:-0}" != 1 ]]; then
  rm -rf "$scratch"
fi
