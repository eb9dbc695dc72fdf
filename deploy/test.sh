#!/usr/bin/env bash
# Builds afr and runs its tests. Three builds, each in its own folder (CMakePresets.json):
#   release  g++ -O2: every target, every test, the format check included       (build/)
#   asan     clang, AddressSanitizer + UndefinedBehaviorSanitizer: the programs the tests run
#            (target afr_tests) and the tests again, plus a 15 s run of each libFuzzer target;
#            left out: the format check, two resident-memory bounds, the three largest
#            seam comparisons (1024-pixel and OpenGL walls, six refreshes without exchange),
#            the 64-image stability comparison and the eval's method ranking: 30 s to
#            minutes of arithmetic each under the sanitizer, with no memory path the smaller
#            seam, wall, reconstructor and eval tests do not take; the release build runs
#            them)                                                        (build-asan/)
#   tsan     clang, ThreadSanitizer: the tests of the concurrent parts (sample ingest and
#            reconstruction, the sampler's worker threads, the channels)       (build-tsan/)
# In both sanitizer builds the test code itself is compiled at -O0, the code under test at -O2
# (tests/CMakeLists.txt): that takes minutes off the build and seconds onto the tests.
# The sanitizer builds' test selection and options are the test presets (ctest --preset asan,
# ctest --preset tsan); suppressions for libraries afr does not build are in cmake/sanitizers/.
# Without a display server the tests run under xvfb-run, so the window test runs too.
#
#   deploy/test.sh                      release, asan and tsan (what CI runs)
#   deploy/test.sh release asan tsan    the named builds, in that order
set -euo pipefail
cd "$(dirname "$0")/.."

builds=("$@")
[ ${#builds[@]} -gt 0 ] || builds=(release asan tsan)
for b in "${builds[@]}"; do
  case "$b" in release|asan|tsan) ;; *) echo "test.sh: unknown build '$b' (release, asan, tsan)" >&2; exit 2 ;; esac
done

run=()
if [ -z "${DISPLAY:-}" ] && command -v xvfb-run >/dev/null; then
  # -noreset: Xvfb otherwise resets when its last client leaves (each window test closes its
  # window), and a test that connects during the reset cannot open the display.
  run=(xvfb-run -a -s "-screen 0 1280x1024x24 -noreset")
fi
jobs=$(nproc)

for b in "${builds[@]}"; do
  echo "== test.sh: $b build"
  start=$SECONDS
  cmake --preset "$b" >/dev/null
  configured=$SECONDS
  cmake --build --preset "$b"
  built=$SECONDS
  # ctest starts the tests it knows to be slow first; a fresh build folder has no timings yet,
  # and the slowest tests come last in definition order, so it gets the ones of a past run.
  dir=build
  [ "$b" = release ] || dir=build-$b
  costs=$dir/Testing/Temporary/CTestCostData.txt
  if [ ! -f "$costs" ] && [ -f "tests/ctest-costs/$b.txt" ]; then
    mkdir -p "$(dirname "$costs")" && cp "tests/ctest-costs/$b.txt" "$costs"
  fi
  if [ "$b" = release ]; then
    "${run[@]}" ctest --test-dir build --output-on-failure -j "$jobs"
  else
    "${run[@]}" ctest --preset "$b" -j "$jobs"
  fi
  echo "== test.sh: $b build passed in $((SECONDS - start)) s (configure" \
    "$((configured - start)) s, build $((built - configured)) s, tests $((SECONDS - built)) s)"
done
