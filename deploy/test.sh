#!/usr/bin/env bash
# Builds afr and runs every test. Three builds, each in its own folder (CMakePresets.json):
#   release  g++ -O2: every test, the format check included          (build/)
#   asan     clang, AddressSanitizer + UndefinedBehaviorSanitizer: every test again, plus a
#            short run of each libFuzzer target                      (build-asan/)
#   tsan     clang, ThreadSanitizer: the tests of the concurrent parts (sample ingest and
#            reconstruction, the sampler's worker threads, the channels)   (build-tsan/)
# Without a display server the tests run under xvfb-run, so the window test runs too.
#
#   deploy/test.sh            the release build (what CI runs)
#   deploy/test.sh release asan tsan    the named builds
set -euo pipefail
cd "$(dirname "$0")/.."

builds=("$@")
[ ${#builds[@]} -gt 0 ] || builds=(release)
for b in "${builds[@]}"; do
  case "$b" in release|asan|tsan) ;; *) echo "test.sh: unknown build '$b' (release, asan, tsan)" >&2; exit 2 ;; esac
done

run=()
if [ -z "${DISPLAY:-}" ] && command -v xvfb-run >/dev/null; then
  run=(xvfb-run -a)
fi
jobs=$(nproc)
supp="$PWD/cmake/sanitizers"

# The tests of the parts that share data between threads.
concurrent='^(ConcurrencyTest|SampleStoreTest|CpuReconstructorTest|SamplerPoolTest|TransportTest)\.'

for b in "${builds[@]}"; do
  echo "== test.sh: $b build"
  start=$SECONDS
  case "$b" in
    release)
      cmake --preset release >/dev/null
      cmake --build --preset release
      "${run[@]}" ctest --test-dir build --output-on-failure -j "$jobs"
      ;;
    asan)
      cmake --preset asan >/dev/null
      cmake --build --preset asan
      # Leaks in Mesa's llvmpipe and the GL loader are theirs, not afr's (cmake/sanitizers/).
      ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:strict_string_checks=1" \
        LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
        UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
        "${run[@]}" ctest --test-dir build-asan --output-on-failure -j "$jobs" \
        --timeout 900 -E '^format_check$'
      ;;
    tsan)
      cmake --preset tsan >/dev/null
      cmake --build --preset tsan --target afr_display_test afr_sampler_test afr_protocol_test
      TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$supp/tsan.supp" \
        "${run[@]}" ctest --test-dir build-tsan --output-on-failure -j "$jobs" -R "$concurrent"
      ;;
  esac
  echo "== test.sh: $b build passed in $((SECONDS - start)) s"
done
