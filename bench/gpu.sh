#!/usr/bin/env bash
# The GPU reconstructor's benchmarks (docs/benchmarks.md, "GPU reconstructor"), the same on a
# GPU server (EGL's device platform, NVIDIA's driver) and here (Mesa's llvmpipe):
#   1. the CPU and OpenGL backends side by side at 256x256 and 512x512 (N = 4 W H), both GL
#      splat passes (gather, raster), GPU time per pass from GL_TIME_ELAPSED queries;
#   2. the OpenGL backend alone at 1920x1080 and 3840x2160 (on a hardware GPU only: llvmpipe
#      takes seconds an image there), and the driver's floor under each splat pass at 256x256
#      and 512x512 (the passes with part of their work left out: --gl-probes);
#   3. a floor under a splat pass binned on the CPU and gathered on the device
#      (afr-bench-binned-gather), the structure a software rasteriser would favour;
#   4. short headless display runs with two samplers (bench/gpu_live.sh) on the GL backend,
#      where display_node and sampler_node are built or bundled: 256x256, and on a hardware
#      GPU 1920x1080 at 60 images/s and 3840x2160 at 30 (the display's stats line names its
#      GPU time per image and its call's phases).
# It writes bench/results/gpu-<renderer>.md (or OUT) with a header naming the renderer, the
# EGL device, the commit and the date, and prints it.
#
#   bench/gpu.sh                                  build/ of this checkout
#   bench/gpu.sh --bin DIR                        a bundle (deploy/bundle.sh DIR build/bench/afr-bench-reconstruct,
#                                                 with build/display_node/display_node build/sampler_node/sampler_node
#                                                 for the display runs)
#   bench/gpu.sh --out FILE --repeats 20 --gpu 1
set -euo pipefail
cd "$(dirname "$0")/.."

bin="" out="" repeats=10 gpu=-1
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --repeats) repeats=$2; shift 2 ;;
    --gpu) gpu=$2; shift 2 ;;
    -h|--help) sed -n '2,22p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "gpu.sh: unknown option '$1'" >&2; exit 2 ;;
  esac
done
if [ -n "$bin" ]; then
  bench=("$bin/run" afr-bench-reconstruct)
else
  bench=(build/bench/afr-bench-reconstruct)
fi
[ -x "${bench[0]}" ] || { echo "gpu.sh: ${bench[0]} not found (build first, or --bin DIR)" >&2; exit 2; }

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# --gl-sync-passes times each pass on a software rasteriser (no timer queries); a GPU ignores it.
common=(--naive false --readback false --gpu "$gpu" --gl-repeats "$repeats" --repeats "$repeats"
  --gl-sync-passes)

"${bench[@]}" "${common[@]}" --backends cpu,gl --threads "$(nproc)" --sizes 256,512 \
  --gl-splat gather,raster --gl-tiles 8,16 | tee "$tmp/small.md"
renderer=$(sed -n 's/^OpenGL: \(.*\) on .*/\1/p' "$tmp/small.md" | head -1)
[ -n "$renderer" ] || { echo "gpu.sh: no OpenGL context (see above)" >&2; exit 1; }
hardware=1
if echo "$renderer" | grep -qiE 'llvmpipe|softpipe|swrast|swiftshader'; then
  hardware=0
  echo "(1920x1080 and 3840x2160 skipped: $renderer is a software rasteriser)" | tee "$tmp/large.md"
else
  "${bench[@]}" "${common[@]}" --backends gl --sizes 1920x1080,3840x2160 --gl-splat gather,raster \
    --gl-tiles 8,16 | tee "$tmp/large.md"
fi

# The driver's floor under each splat pass, side by side with the passes and the CPU backend in
# one run: the probes (GlProbe, gl_reconstructor.h) leave out part of a pass (culled: no
# rasterising; flat: no kernel; dots: one-pixel points; visit: the gather's candidates loaded and
# added, no kernel), so what is left bounds what any kernel on this driver can take.
"${bench[@]}" "${common[@]}" --backends cpu,gl --threads "$(nproc)" --sizes 256,512 \
  --gl-splat gather,raster --gl-tiles 16 --gl-probes none,culled,flat,dots,visit | tee "$tmp/probes.md"

# A floor under the structure that needs neither the device's atomics nor a point per sample:
# the samples binned by pixel on the CPU, gathered on the device (afr-bench-binned-gather; not a
# backend: docs/benchmarks.md, "The one structure that comes near"). Skipped where a
# bundle lacks it.
if [ -n "$bin" ]; then
  binned=("$bin/run" afr-bench-binned-gather)
  [ -x "$bin/bin/afr-bench-binned-gather" ] || binned=()
else
  binned=(build/bench/afr-bench-binned-gather)
  [ -x "${binned[0]}" ] || binned=()
fi
if [ ${#binned[@]} -gt 0 ]; then
  "${binned[@]}" --gpu "$gpu" --repeats "$repeats" --sizes 256,512 --reach 2,3 --block 1,2,4,0 |
    tee "$tmp/binned.md"
else
  echo "(afr-bench-binned-gather not built or bundled)" | tee "$tmp/binned.md"
fi

# The display runs (bench/gpu_live.sh) with the nodes of build/ or of the bundle (which must
# hold display_node and sampler_node: deploy/bundle.sh DIR build/display_node/display_node
# build/sampler_node/sampler_node build/bench/afr-bench-reconstruct). 256x256 everywhere; on a
# hardware GPU also 1920x1080 at 60 images/s and 3840x2160 at 30 (the targets of the benchmark
# above, live), the samplers given the cores the display leaves (gpu_live.sh's default).
nodes=()
if [ -n "$bin" ]; then
  [ -x "$bin/bin/display_node" ] && [ -x "$bin/bin/sampler_node" ] && nodes=(--bin "$bin")
elif [ -x build/display_node/display_node ] && [ -x build/sampler_node/sampler_node ]; then
  nodes=(--build build)
fi
runs=("256x256 30 --threads 1")
if [ "$hardware" = 1 ]; then
  runs+=("1920x1080 60" "3840x2160 30")
fi
display=""
if [ ${#nodes[@]} -gt 0 ]; then
  for r in "${runs[@]}"; do
    read -r size fps more <<<"$r"
    # shellcheck disable=SC2086
    display+=$(bench/gpu_live.sh "${nodes[@]}" --size "$size" --fps "$fps" $more --rounds 1 \
      --seconds 12 --gpu "$gpu" 2>&1 || true)$'\n'
  done
fi

slug=$(echo "$renderer" | tr 'A-Z' 'a-z' | sed 's/[^a-z0-9]\{1,\}/-/g; s/^-//; s/-$//' | cut -c1-40)
out=${out:-bench/results/gpu-$slug.md}
if [ -n "$bin" ] && [ -f "$bin/COMMIT" ]; then
  commit="$(cat "$bin/COMMIT") (the bundle's programs)" dirty=""
else
  commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
  dirty=$(git status --porcelain 2>/dev/null | grep -qv '^??' && echo " (with uncommitted changes)" || true)
fi
{
  echo "# GPU reconstructor: $renderer"
  echo
  echo "The GL backend's splat passes and the CPU backend, N = 4 W H, 1/60 of N new samples per"
  echo "refresh, nothing read back (docs/benchmarks.md, \"GPU reconstructor\")."
  echo
  echo "- command: \`bench/gpu.sh${bin:+ --bin DIR} --repeats $repeats --gpu $gpu\`"
  echo "- commit: $commit$dirty; date: $(date -u +%Y-%m-%d); $(nproc) cores"
  echo
  cat "$tmp/small.md"
  echo
  cat "$tmp/large.md"
  echo
  echo "## The driver's floor under each splat pass"
  echo
  echo "The passes again with part of their work left out (afr-bench-reconstruct --gl-probes;"
  echo "GlProbe in display_node/include/afr/display/gl_reconstructor.h): culled, every point culled"
  echo "after the vertex stage (no rasterising); flat, the points drawn and blended at a constant"
  echo "weight (no kernel, no discard); dots, flat with one-pixel points; visit, the gather's"
  echo "candidates loaded and added (no kernel). Their images are wrong by design."
  echo
  cat "$tmp/probes.md"
  echo
  echo "## A floor under a gather binned on the CPU"
  echo
  echo "The samples counted into per-pixel cells on the CPU (one thread), uploaded, and gathered"
  echo "by a compute pass with the splat kernel's arithmetic, one invocation per block of pixels"
  echo "visiting the cells within reach (bench/binned_gather_bench.cpp). Every splat is as wide as"
  echo "the reach allows (reach + 0.5 px); the reprojection, the splat shapes, wider splats and the"
  echo "hole fill are not timed, so a pass of this design takes at least the sum."
  echo
  cat "$tmp/binned.md"
  if [ -n "$display" ]; then
    echo
    echo "Headless display runs (bench/gpu_live.sh: deploy/run-local.sh 2, 12 s, GL backend, the built-in scene):"
    echo
    echo '```'
    printf '%s' "$display"
    echo '```'
  fi
} >"$out"
echo "gpu.sh: wrote $out"
