#!/usr/bin/env bash
# Regenerates the measured figures in bench/results/ (bench/results/README.md lists them).
# Each result has a name; the script runs the named results' commands and writes each file
# with a header: what it measures, the command, the commit (and whether the tree had
# uncommitted changes), the date, the cores and the load average at the start. A file is
# replaced only when its command succeeded.
#
#   bench/refresh_results.sh --list                 every result, its file and its command
#   bench/refresh_results.sh liveness protocol      run those two
#   bench/refresh_results.sh --build build-rel tracer
#   bench/refresh_results.sh eval-256 eval-timing results-doc   Table 1, its cost, docs/results.md
#   bench/refresh_results.sh all                    every result (many hours; root ones need root)
#
# Use a Release build (default build/). The commands are the ones the docs name; results that
# need the BART kitchen convert it first into out/kitchen/ (../shared/scenes must exist).
# goodput and lossy need root (network namespaces) and are skipped without it. Run one
# benchmark at a time on an otherwise quiet machine: the figures move with the load.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
BUILD=build

names=()
declare -A FILE TITLE WHAT CMD FLAGS
# add NAME FILE TITLE WHAT CMD [FLAGS]: a result whose body is the command's standard output
# (CMD is evaluated by bash with $BUILD set; it may be several commands). FLAGS: "root" (needs
# root), "self" (the command writes its result file itself, with its own header).
add() {
  names+=("$1")
  FILE[$1]=$2 TITLE[$1]=$3 WHAT[$1]=$4 CMD[$1]=$5 FLAGS[$1]=${6:-}
}

add liveness liveness.md "Liveness of the running service" \
  "Detection of a kill -9, stops that must not count as deaths, samplers back after a display restart (docs/service.md, \"Liveness\")." \
  'python3 bench/liveness.py --build "$BUILD" --trials 5 --load 0 --write' \
  self
add gpu "gpu-llvmpipe-llvm-15-0-6-256-bits.md" "GPU reconstructor" \
  "The GL backend's splat passes beside the CPU backend (docs/benchmarks.md, \"GPU reconstructor\"); the file is named after the renderer." \
  'bench/gpu.sh' \
  self
add liveness-load4 liveness-load4.md "Liveness of the running service, four busy processes beside" \
  "As liveness.md with four busy processes beside the nodes (docs/service.md, \"Liveness\")." \
  'python3 bench/liveness.py --build "$BUILD" --trials 5 --load 4 --write' \
  self
add tracer tracer.md "Tracer throughput" \
  "Shaded samples per second of the Embree tracer on the built-in scene and the BART kitchen (docs/benchmarks.md, \"Tracer\")." \
  'need_kitchen && "$BUILD"/bench/afr-bench-tracer --scene out/kitchen/kitchen.gltf'
add tracer-deforming tracer-deforming.md "Tracer and sampler on deforming meshes" \
  "A skinned and morphed sheet of 64 x 64 and 256 x 256 vertices: what Tracer::set_time costs (deformation, velocities, refit), the tracer's samples/s, and a one-thread sampler's samples/s animated and frozen in its pose (docs/benchmarks.md, \"Deforming meshes\")." \
  'for n in 64 256; do "$BUILD"/bench/afr-bench-tracer --no-builtin --deforming $n --times 0,1,2,3 || exit 1; echo; done'
add tracer-forest tracer-forest.md "Shared static meshes: copies or instances" \
  "A forest of 16 to 4096 copies of one 2,145-vertex mesh, held by the tracer as world-space copies and as instances of the mesh's one BVH: build time, vertices copied, set_time and random-ray samples/s on one thread (TracerOptions::max_copied_vertices; docs/benchmarks.md, \"Tracer\")." \
  '"$BUILD"/bench/afr-bench-tracer --no-builtin --forest 16 --forest 64 --forest 256 --forest 4096 --samples 100000 --repeats 5'
add pool-memory pool-memory.md "A sampler's memory and start-up against its threads" \
  "Peak resident memory of a sampler_node and its seconds from the scene loaded to sampling, with 1, 2 and 4 threads, on a static scene of 2 million triangles (docs/sampler.md, \"Threads\")." \
  'python3 bench/pool_memory.py --build "$BUILD" --repeats 3 --threads 1,2,4'
add light-samples light-samples.md "Light picking" \
  "Time and error of afr-render against the light samples per surface on scenes of 64 and 256 lights, and the running service's error and rate with and without picking, with a still and a moving view, with the preset's store and one 2.5 times as deep (docs/sampler.md, \"Many lights\")." \
  'python3 bench/light_samples.py --build "$BUILD" --repeats 3'
add ideal-render ideal-render.md "Ideal renderer" \
  "Wall time and rays per second of the ideal renderer for one 256x256 frame of the kitchen at 16 spp (docs/benchmarks.md, \"Ideal renderer\")." \
  'need_kitchen && "$BUILD"/bench/afr-render out/kitchen/kitchen.gltf --time 6 --size 256x256 --spp 16 -o out/kitchen_t6.png'
add sampler-control sampler-control.md "Cost of the sampler's adaptive control" \
  "Adaptive and uniform samples per CPU-second on one thread, their ratio (goal >= 0.90), reprojection and occlusion per new crosshair (goal <= 1/50), pool samples/s (docs/benchmarks.md, \"Sampler control\")." \
  'need_kitchen && "$BUILD"/bench/afr-bench-sampler --scene out/kitchen/kitchen.gltf --seconds 1 --repeats 5'
add sampler-instructions sampler-instructions.md "Instructions per step of the adaptive sampler" \
  "Callgrind's instruction totals of fixed, seeded runs of each sampler mode, with the step counts the program prints (docs/benchmarks.md, \"Sampler control\"); divide the totals by the counts for per-step figures." \
  'need_kitchen && mkdir -p out/callgrind && for scene in "" out/kitchen/kitchen.gltf; do for ms in "adaptive 5000" "uniform 30000" "crosshair 3000" "reproject 20000"; do set -- $ms; echo "### --profile $1 --steps $2 ${scene:+--scene $scene}"; echo; valgrind --tool=callgrind --callgrind-out-file=out/callgrind/%p --toggle-collect="*profile_steps*" "$BUILD"/bench/afr-bench-sampler --profile "$1" --steps "$2" ${scene:+--scene "$scene"} 2>&1 | grep -E "steps:|Collected" | sed "s/^==[0-9]*== //;s/^/    /" || exit 1; echo; done; done'
add sampler-memory sampler-memory.md "Sampler heap per region pixel" \
  "Heap a sampler takes per pixel of its region, with a crosshair in every pixel and with one pixel in 64 holding one, b = 1 and 4 (docs/sampler.md, \"Memory\")." \
  '"$BUILD"/tests/sampler_node/afr_sampler_memory_test --gtest_filter="*HeapPerRegionPixel*"'
add reconstruct reconstruct.md "Reconstruction time by resolution and backend" \
  "Wall time of one live refresh (1/60 of N new samples and a tiling, then reconstruct with reprojection of N = 4 x pixels samples) for the CPU and OpenGL backends, with the naive 3x3 splat as yardstick (docs/reconstruction.md, \"Benchmark\")." \
  '"$BUILD"/bench/afr-bench-reconstruct --sizes 256,512,1024 --backends cpu,gl --threads 1,2 --repeats 11 --gl-repeats 3 --warmup 8'
add reconstruct-goal reconstruct-goal.md "Reconstruction at 256 x 256: the 60 Hz goal" \
  "The CPU backend at 256x256, N = 262 144, on 1 and 2 threads; the goals are <= 16.7 ms per refresh on 2 threads and <= 1.3 x the naive 3x3 yardstick on one, also measured in alternating rounds (docs/reconstruction.md, \"Benchmark\")." \
  '"$BUILD"/bench/afr-bench-reconstruct --sizes 256 --backends cpu --threads 1,2 --repeats 31 --warmup 10 --alternate 15 --per-round 10'
add reconstruct-clones reconstruct-clones.md "CPU reconstructor: the x86-64-v3 clones against the baseline build" \
  "The CPU backend at 256x256, N = 262 144, on 1 and 2 threads, and the naive 3x3 yardstick, in a build with the hot passes' x86-64-v3 clones (the default) and one without (-DAFR_CPU_CLONES=OFF, build-noclones/), 5 runs of each alternating; per build the median over the runs of each row's median and of the 1-thread row over the yardstick (docs/reconstruction.md, \"Benchmark\"). Make build-noclones first: cmake -S . -B build-noclones -G Ninja -DCMAKE_BUILD_TYPE=Release -DAFR_CPU_CLONES=OFF && cmake --build build-noclones --target afr-bench-reconstruct" \
  'clone_table build-noclones "$BUILD" 5'
add reconstruct-before-after reconstruct-before-after.md "CPU reconstructor: 6598d90 against this commit" \
  "The CPU backend at 256x256, N = 262 144, on one thread against the naive 3x3 yardstick in alternating rounds (afr-bench-reconstruct --alternate 15 --per-round 10: on a shared host the p10s are the stable figures), in a build of 6598d90 (before the one-group small splats, the 8-pixel shape pass, the ring prefetch and the paged bins) with this commit's benchmark and in this one, 5 runs of each alternating (docs/reconstruction.md, \"Benchmark\"). Make build-before first: git worktree add /tmp/afr-6598d90 6598d90 && cp bench/reconstruct_bench.cpp /tmp/afr-6598d90/bench/ && cmake -S /tmp/afr-6598d90 -B build-before -G Ninja -DCMAKE_BUILD_TYPE=Release && cmake --build build-before --target afr-bench-reconstruct" \
  'alternating_table build-before "$BUILD" 5'
add service-cap40k service-cap40k.md "Service on loopback: k samplers capped at 40 000 samples/s" \
  "k = 1..4 capped samplers and a headless display (128x128, CPU backend, 60 Hz): received / sum of caps (goal >= 0.95), latency p50 / p99 (goal p50 <= 18.7 ms), batch bytes per sample (docs/service.md, \"Figures\")." \
  'deploy/lan/bench.sh --build "$BUILD" --cap 40000'
add service-cap100k service-cap100k.md "Service on loopback: k samplers capped at 100 000 samples/s" \
  "As service-cap40k.md with caps of 100 000 samples/s (docs/service.md, \"Figures\")." \
  'deploy/lan/bench.sh --build "$BUILD" --cap 100000'
add ingest ingest.md "Display ingest" \
  "BM_Ingest: the display's ingest thread's CPU time per sample and the rate that arrives over TCP loopback, with and without the sample store; BM_StoreAppend: the store alone (docs/service.md, \"Figures\")." \
  '"$BUILD"/bench/afr-bench-service 2>&1'
add goodput goodput.md "Goodput of sample batches across a 1 Gbit link" \
  "Afr batch bytes received per second over a tbf-limited 1 Gbit link between two network namespaces, over the link rate (ceiling 0.954, goal >= 0.90) (docs/service.md, \"Figures\")." \
  'for args in "--seconds 8 --repeats 5 --receiver ingest --mode flush" "--seconds 8 --repeats 5 --receiver display --mode drop" "--seconds 6 --repeats 1 --receiver ingest --mode drop -- --sndhwm 1000"; do echo "### deploy/lan/goodput.sh --build $BUILD $args"; echo; deploy/lan/goodput.sh --build "$BUILD" $args || exit 1; echo; done' \
  root
add flow flow.md "Flow control of real samplers across a 100 Mbit link" \
  "Two samplers (one thread each) and a headless display in network namespaces, tbf 100 mbit on every link (the display's link the bottleneck), 3 runs of 20 s: afr bytes received per second against the link, batches dropped from the samplers' send queues against those received, gaps, refresh, latency (docs/service.md, \"Figures\")." \
  'bench/flow.sh --build "$BUILD" --rate 100mbit --samplers 2 --seconds 20 --repeats 3' \
  root
add flow-32k flow-32k.md "Flow control of real samplers across a 100 Mbit link, 32 KiB send buffers" \
  "As flow.md with sampler_node --send-buffer 32768 (docs/protocol.md, \"Transport\")." \
  'bench/flow.sh --build "$BUILD" --rate 100mbit --samplers 2 --seconds 20 --repeats 3 --send-buffer 32768' \
  root
add protocol protocol.md "Protocol: codec cost and loopback throughput" \
  "Encode and decode cost per sample, tiling decode, PUSH/PULL throughput over TCP loopback with and without CurveZMQ, a non-blocking sender with and without the ZMQ_EVENTS check (docs/protocol.md, \"Figures\")." \
  '"$BUILD"/bench/afr-bench-protocol --benchmark_min_time=1 2>&1'
add eval-256 eval-table-256.md "Table 1 at 256 x 256" \
  "Mean RMS error (0-255) against the ideal renderer of every method at 100K, 400K and 800K rays/s on the four animations, mean and range over 3 seeds, latency one refresh for every method, occlusion rays charged; adaptive against every other method beyond the spread; the wall time of each run (docs/evaluation.md); the program's table.md." \
  'need_kitchen && "$BUILD"/bench/afr-eval --size 256x256 --seconds 3 --spp 9 --out out/eval/table-256 >&2 && cat out/eval/table-256/table.md'
add eval-512 eval-table-512.md "Table 1 at 512 x 512" \
  "Mean RMS error of every method at 400K and 1.6M primary rays/s on the three kitchen animations at 512 x 512 (docs/evaluation.md); the program's table.md." \
  'need_kitchen && "$BUILD"/bench/afr-eval --size 512x512 --seconds 1 --spp 4 --animations bart,toycar,interactive --rates 400K,1.6M --out out/eval/table-512 >&2 && cat out/eval/table-512/table.md'
add eval-timing eval-timing.md "Cost of a full Table 1 run" \
  "Wall minutes of a whole Table-1 run of the first 20 s of each kitchen animation (its keys end there) at 256 x 256, every method at 100K, 400K and 800K, 3 seeds, with the 9-spp ideal frames read from a warm cache (the first command renders any that are missing); the target is 30 minutes (docs/evaluation.md, \"Cost of a full Table 1 run\"); the program's table.md." \
  'need_kitchen && "$BUILD"/bench/afr-eval --ideal-only --size 256x256 --seconds 20 --start bart=0 toycar=0 interactive=0 --spp 9 --animations bart,toycar,interactive >&2 && "$BUILD"/bench/afr-eval --size 256x256 --seconds 20 --start bart=0 toycar=0 interactive=0 --spp 9 --animations bart,toycar,interactive --out out/eval/table1-timing >&2 && cat out/eval/table1-timing/table.md'
add eval-timing-paper eval-timing-paper.md "Cost of the paper's Table 1 run" \
  "As eval-timing with the paper's five Table-1 methods only (framed 60 Hz, framed full res, traditional frameless, adaptive, full res 60 Hz), without the two afr-eval adds (adaptive without reprojection, the paper's Figure 8; framed 60 Hz + TAA); the target is 30 minutes (docs/evaluation.md, \"Cost of a full Table 1 run\"); the program's table.md." \
  'need_kitchen && "$BUILD"/bench/afr-eval --ideal-only --size 256x256 --seconds 20 --start bart=0 toycar=0 interactive=0 --spp 9 --animations bart,toycar,interactive >&2 && "$BUILD"/bench/afr-eval --size 256x256 --seconds 20 --start bart=0 toycar=0 interactive=0 --spp 9 --animations bart,toycar,interactive --methods framed-60hz,framed-full-res,frameless,adaptive,full-res-60hz --out out/eval/table1-timing-paper >&2 && cat out/eval/table1-timing-paper/table.md'
add coverage-rule coverage-rule.md "Table 1 with the former and the current coverage rule" \
  "The adaptive cells of Table 1 (256 x 256, 3 s, 100K/400K/800K, 3 seeds, the fair rules) with the former thresholds rule (x4 below 4 splats, x0.7 above 32) and with the continuous one, side by side at one commit; a cell differs only where the ranges over the seeds do not overlap (docs/reconstruction.md, \"Why continuous\")." \
  'need_kitchen && for rule in thresholds continuous; do "$BUILD"/bench/afr-eval --methods adaptive --coverage-rule $rule --size 256x256 --seconds 3 --spp 9 --jobs 1 --threads 1 --no-progress --out out/eval/rule-$rule >&2 || exit 1; done && compare_cells "thresholds" out/eval/rule-thresholds "continuous" out/eval/rule-continuous'
add occlusion-term occlusion-term.md "Table 1's adaptive cells over 20 s with and without the occlusion term" \
  "The adaptive cells of the timed Table 1 (256 x 256, the first 20 s of each kitchen animation, 100K/400K/800K, 3 seeds, the fair rules) with section 6.1's weights kappa 0.6, lambda 0.2 (the occlusion term gets 0.2) and kappa 0.6, lambda 0.4 (it gets none), side by side at one commit; a cell differs only where the ranges over the seeds do not overlap (docs/sampler.md, \"The occlusion term\")." \
  'need_kitchen && for l in 0.2 0.4; do "$BUILD"/bench/afr-eval --methods adaptive --lambda $l --kappa 0.6 --size 256x256 --seconds 20 --start bart=0 toycar=0 interactive=0 --spp 9 --animations bart,toycar,interactive --no-progress --no-plots --out out/eval/occlusion-lambda-$l >&2 || exit 1; done && compare_cells "lambda 0.2" out/eval/occlusion-lambda-0.2 "lambda 0.4" out/eval/occlusion-lambda-0.4'
add filter-extent filter-extent.md "Table 1's adaptive cells with the largest filter extent at 4 px" \
  "The adaptive cells of Table 1 (256 x 256, 3 s, 100K/400K/800K, 3 seeds, the fair rules) with FilterLimits' default largest e_x, e_y (16 px) and with 4 px (--max-extent 4), the one knob the sweep found lower or level on all four animations; a cell differs only where the ranges over the seeds do not overlap (docs/tradeoffs.md, \"What they say\")." \
  'need_kitchen && for e in 16 4; do "$BUILD"/bench/afr-eval --methods adaptive --max-extent $e --size 256x256 --seconds 3 --spp 9 --no-progress --out out/eval/extent-$e >&2 || exit 1; done && compare_cells "max e_xy 16" out/eval/extent-16 "max e_xy 4" out/eval/extent-4'
add eval-robots eval-robots-256.md "The targets on BART robots at 256 x 256" \
  "Every method at 100K, 400K and 800K rays/s on BART's robots from 14 s (the camera closes in on a robot and turns away), 3 s, 3 seeds, the rules of eval-256 (docs/results.md, \"Other scenes\"); the program's table.md." \
  'need_robots && "$BUILD"/bench/afr-eval --scene out/robots/robots.gltf --camera own --start 14 --size 256x256 --seconds 3 --spp 9 --no-progress --out out/eval/robots-256 >&2 && cat out/eval/robots-256/table.md'
add eval-boxanimated eval-boxanimated-256.md "The targets on a Khronos glTF sample model at 256 x 256" \
  "Every method at 100K, 400K and 800K rays/s on BoxAnimated (tests/data/khronos: no lights, no camera: the default headlight and camera) from 0.5 s, 3 s, 3 seeds, the rules of eval-256 (docs/results.md, \"Other scenes\"); the program's table.md." \
  '"$BUILD"/bench/afr-eval --scene tests/data/khronos/BoxAnimated.gltf --camera own --start 0.5 --size 256x256 --seconds 3 --spp 9 --no-progress --out out/eval/boxanimated-256 >&2 && cat out/eval/boxanimated-256/table.md'
add eval-256-gpu-display eval-table-256-gpu-display.md "Table 1 for a GPU display at 256 x 256" \
  "As eval-256 with the display's latency at 1/4 refresh (--latency 0.25): what a display that reconstructs on a GPU pays (docs/benchmarks.md, \"GPU reconstructor\": 0.6-0.7 ms of GPU time at 256 x 256 on an H200, a live call of 1.9 ms). The framed methods keep their one refresh: a frame traced at rate R takes the whole refresh (docs/results.md, \"For a GPU display\"); the program's table.md." \
  'need_kitchen && "$BUILD"/bench/afr-eval --latency 0.25 --size 256x256 --seconds 3 --spp 9 --no-progress --out out/eval/table-256-gpu-display >&2 && cat out/eval/table-256-gpu-display/table.md'
add eval-robots-gpu-display eval-robots-256-gpu-display.md "BART robots for a GPU display at 256 x 256" \
  "As eval-robots with the display's latency at 1/4 refresh (--latency 0.25), the framed methods at their one refresh (docs/results.md, \"For a GPU display\"); the program's table.md." \
  'need_robots && "$BUILD"/bench/afr-eval --latency 0.25 --scene out/robots/robots.gltf --camera own --start 14 --size 256x256 --seconds 3 --spp 9 --no-progress --out out/eval/robots-256-gpu-display >&2 && cat out/eval/robots-256-gpu-display/table.md'
add results-doc ../../docs/results.md "The tables of docs/results.md" \
  "The targets, other-scene, GPU-display and timing tables of docs/results.md, made by bench/eval_tables.py from the outputs of eval-256, eval-robots, eval-boxanimated, eval-256-gpu-display, eval-robots-gpu-display, eval-timing and eval-timing-paper (run those first)." \
  'python3 bench/eval_tables.py --table out/eval/table-256 $(for d in table1-timing table1-timing-paper; do [ -d out/eval/$d ] && echo --timing out/eval/$d; done) --scene out/eval/robots-256 --scene out/eval/boxanimated-256 $(for d in table-256-gpu-display robots-256-gpu-display; do [ -d out/eval/$d ] && echo --gpu-display out/eval/$d; done) --write docs/results.md' \
  self
add sweep sweep-256.md "Speed/accuracy sweep at 256 x 256" \
  "Mean RMS (mean and range over 3 seeds) and wall-clock cost on one thread of one knob at a time and of the baselines, each point against the defaults beyond the spread, Pareto fronts marked (docs/tradeoffs.md); the program's sweep.md." \
  'need_kitchen && "$BUILD"/bench/afr-eval --sweep --size 256x256 --seconds 2 --spp 9 --seeds 3 --jobs 1 --threads 1 --no-progress --out out/eval/sweep-256 >&2 && cat out/eval/sweep-256/sweep.md'
add latency latency.md "Adaptive's latency between 0 and 1 refresh" \
  "Mean RMS (mean and range over 3 seeds) of adaptive at 400K, 256 x 256, with the display's latency at 0, 1/4, 1/2 and 1 refresh (a reconstruction that takes that much of a refresh), beside framed 60 Hz and framed 60 Hz + TAA at their one refresh; where adaptive is below or above each baseline beyond the spread (docs/results.md, \"Where the targets are not met\")." \
  'need_kitchen && for l in 0 0.25 0.5 1; do "$BUILD"/bench/afr-eval --methods adaptive --rates 400K --latency $l --size 256x256 --seconds 3 --spp 9 --no-progress --no-plots --out out/eval/latency-$l >&2 || exit 1; done && "$BUILD"/bench/afr-eval --methods framed-60hz,framed-taa --rates 400K --size 256x256 --seconds 3 --spp 9 --no-progress --no-plots --out out/eval/latency-base >&2 && latency_table out/eval/latency-base out/eval/latency-{0,0.25,0.5,1}'
add presets presets.md "Presets at 400K" \
  "Mean RMS per animation and wall seconds of each preset at 400K on the four animations (docs/tradeoffs.md, \"Presets\"); the three runs' table.md." \
  'need_kitchen && for p in fast balanced accurate; do "$BUILD"/bench/afr-eval --methods adaptive --rates 400K --seconds 2 --spp 9 --preset $p --out out/eval/preset-$p >&2 || exit 1; echo "## --preset $p"; echo; cat out/eval/preset-$p/table.md; echo; done'
add control-weights control-weights.md "The sampler's control weights: kappa, lambda, m, i" \
  "Mean RMS (0-255) over sampler seeds, with the lowest and highest seed, of adaptive at 400K with one control weight changed at a time, four animations at 128 x 128 (docs/sampler.md, \"How kappa, lambda, m and i were chosen\")." \
  'need_kitchen && for s in 1 2 3 4 5; do "$BUILD"/bench/afr-eval --m 2 --sweep --knobs kappa,lambda,m,i --animations builtin --size 128x128 --seconds 2 --spp 9 --seed $s --seeds 1 --out out/eval/ctl-builtin-s$s >&2 || exit 1; done && for s in 1 2; do "$BUILD"/bench/afr-eval --m 2 --sweep --knobs kappa,lambda,m,i --animations bart,toycar,interactive --size 128x128 --seconds 2 --spp 9 --seed $s --seeds 1 --out out/eval/ctl-kitchen-s$s >&2 || exit 1; done && for s in 1 2; do "$BUILD"/bench/afr-eval --sweep --knobs kappa,lambda --animations bart,toycar,interactive,builtin --size 128x128 --seconds 2 --spp 9 --seed $s --seeds 1 --out out/eval/ctl-m1-s$s >&2 || exit 1; done && seed_means "around the former defaults (m = 2)" out/eval/ctl-builtin-s{1..5} out/eval/ctl-kitchen-s{1,2} && seed_means "around the chosen defaults (m = 1)" out/eval/ctl-m1-s{1,2}'
add fuzz fuzz.md "Long fuzzing runs" \
  "Executions, speed and crashes of 10 million executions of each libFuzzer target in the asan build (docs/robustness.md, \"Fuzzing\")." \
  'for t in protocol aff gltf camera_path; do AFR_BUILD_DIR=build-asan AFR_FUZZ_KEEP=1 bench/fuzz.sh $t 0 -runs=10000000 | grep "^afr_fuzz_" | sed "s/^/    /" || exit 1; done'
add soak soak.md "Soak run" \
  "Ten minutes of 4 samplers and a headless display with a sampler killed every 30 s: RSS, store, queues, errors, image error (docs/robustness.md, \"Soak\"); the script's report." \
  'python3 deploy/soak.py --build "$BUILD" --minutes 10 --samplers 4 --kill-every 30'
add lossy lossy-lan.md "Lossy LAN" \
  "The service across network namespaces on clean links and on 100 mbit links with 5% drops, 3 runs each, image error against the ideal render (docs/robustness.md, \"Lossy LAN\")." \
  'deploy/lan/lossy.sh --build "$BUILD" --repeats 3' \
  root

# The BART scenes in glTF, for the results that use them (docs/benchmarks.md), converted again
# whenever the converter is newer than the conversion: a conversion left from an older
# aff2gltf would give figures of another scene (the ideal frames' cache is keyed by the
# scene's content, so a conversion that changed nothing reuses them).
need_robots() {
  [ out/robots/robots.gltf -nt "$BUILD"/tools/aff2gltf/aff2gltf ] && return 0
  "$BUILD"/tools/aff2gltf/aff2gltf ../shared/scenes/bart-robots/aff/Robot.aff \
    -o out/robots/robots.gltf >&2
}

need_kitchen() {
  [ out/kitchen/kitchen.gltf -nt "$BUILD"/tools/aff2gltf/aff2gltf ] && return 0
  "$BUILD"/tools/aff2gltf/aff2gltf ../shared/scenes/bart-kitchen/aff/kitchen.aff \
    -o out/kitchen/kitchen.gltf >&2
}

# clone_table BUILD_A BUILD_B RUNS: afr-bench-reconstruct at 256x256 (CPU, 1 and 2 threads,
# the naive yardstick) from two build folders, RUNS runs each alternating; per build the median
# over the runs of each row's median ms and of the 1-thread row over the yardstick, then every
# run's ratio.
clone_table() {
  local a=$1 b=$2 runs=$3 raw
  raw=$(mktemp)
  for i in $(seq 1 "$runs"); do
    for d in "$a" "$b"; do
      "$d"/bench/afr-bench-reconstruct --sizes 256 --backends cpu --threads 1,2 --repeats 31 \
        --warmup 10 | grep -E '^\| (naive|cpu)' | sed "s|^|$d |" >>"$raw" || return 1
    done
  done
  python3 - "$raw" "$a" "$b" <<'PY'
import statistics, sys
raw, builds = sys.argv[1], sys.argv[2:4]
lines = {b: [] for b in builds}  # per build: each row's median ms, in the order printed
for line in open(raw):
    build, rest = line.split(" ", 1)
    cells = [c.strip() for c in rest.strip().strip("|").split("|")]
    lines[build].append(float(cells[4]))
# Each run printed three rows: the yardstick, then the CPU backend on 1 and on 2 threads.
merged = {b: [dict(zip(("naive", "cpu1", "cpu2"), v[k:k + 3])) for k in range(0, len(v), 3)]
          for b, v in lines.items()}
print("| build | naive 3x3 ms | cpu 1 thread ms | cpu 2 threads ms | 1 thread / naive | each run's 1 thread / naive |")
print("|---|---:|---:|---:|---:|---|")
for b in builds:
    r = merged[b]
    med = lambda k: statistics.median(x[k] for x in r)
    ratios = [x["cpu1"] / x["naive"] for x in r]
    print(f"| {b} | {med('naive'):.2f} | {med('cpu1'):.2f} | {med('cpu2'):.2f} | "
          f"{statistics.median(ratios):.2f} | {', '.join(f'{v:.2f}' for v in ratios)} |")
PY
  rm -f "$raw"
}
# alternating_table BUILD_A BUILD_B RUNS: the CPU backend at 256x256 on one thread against the
# yardstick in alternating rounds (afr-bench-reconstruct --alternate), runs of the two builds
# alternating; per build the median over the runs of the yardstick's p10, the backend's p10
# and their ratio, and each run's ratio.
alternating_table() {
  local a=$1 b=$2 runs=$3 raw
  raw=$(mktemp)
  for i in $(seq 1 "$runs"); do
    for d in "$a" "$b"; do
      "$d"/bench/afr-bench-reconstruct --sizes 256 --backends cpu --threads 1 --repeats 3 \
        --warmup 10 --naive 0 --alternate 15 --per-round 10 |
        grep -E '^\| 1 \| 256x256 \| 15 x 10' | sed "s|^|$d |" >>"$raw" || return 1
    done
  done
  python3 - "$raw" "$a" "$b" <<'PY'
import statistics, sys
raw, builds = sys.argv[1], sys.argv[2:4]
rows = {b: [] for b in builds}  # per build, per run: (yardstick p10, cpu p10)
for line in open(raw):
    build, rest = line.split(" ", 1)
    cells = [c.strip() for c in rest.strip().strip("|").split("|")]
    rows[build].append((float(cells[7]), float(cells[8])))
print("| build | yardstick p10 ms | cpu 1 thread p10 ms | ratio of p10s | each run's ratio |")
print("|---|---:|---:|---:|---|")
for b in builds:
    r = rows[b]
    ratios = [c / y for y, c in r]
    print(f"| {b} | {statistics.median(y for y, _ in r):.2f} | "
          f"{statistics.median(c for _, c in r):.2f} | {statistics.median(ratios):.3f} | "
          f"{', '.join(f'{v:.3f}' for v in ratios)} |")
PY
  rm -f "$raw"
}
# compare_cells LABEL_A DIR_A LABEL_B DIR_B: the cells of two afr-eval runs side by side (their
# cells.csv), with B against A beyond the spread over the seeds.
compare_cells() {
  python3 - "$@" <<'PY'
import csv, sys
la, da, lb, db = sys.argv[1:5]
def cells(d):
    with open(f"{d}/cells.csv") as f:
        return {(r["animation"], r["method"], float(r["rate"])): r for r in csv.DictReader(f)}
a, b = cells(da), cells(db)
print(f"| animation | method | R | {la} | {lb} | {lb} against {la} |")
print("|---|---|---:|---:|---:|:-:|")
for key in a:
    if key not in b:
        continue
    x, y = a[key], b[key]
    lo_x, hi_x, lo_y, hi_y = (float(x["min_rms"]), float(x["max_rms"]),
                              float(y["min_rms"]), float(y["max_rms"]))
    verdict = "**lower**" if hi_y < lo_x else "**higher**" if lo_y > hi_x else "within spread"
    show = lambda r: f'{float(r["mean_rms"]):.2f} ({float(r["min_rms"]):.2f}-{float(r["max_rms"]):.2f})'
    print(f"| {key[0]} | {key[1]} | {key[2] / 1e3:.0f}K | {show(x)} | {show(y)} | {verdict} |")
PY
}
# latency_table BASE DIR...: adaptive's cells of each DIR (afr-eval outputs at one latency
# each, read from run.json) against framed 60 Hz and framed 60 Hz + TAA of BASE, per animation.
latency_table() {
  python3 - "$@" <<'PY'
import csv, json, sys
base, dirs = sys.argv[1], sys.argv[2:]
def cells(d):
    with open(f"{d}/cells.csv") as f:
        return {(r["animation"], r["method"]): r for r in csv.DictReader(f)}
def latency(d):
    with open(f"{d}/run.json") as f:
        return json.load(f)["latency_refreshes"]
b = cells(base)
runs = [(latency(d), cells(d)) for d in dirs]
show = lambda r: f'{float(r["mean_rms"]):.2f} ({float(r["min_rms"]):.2f}-{float(r["max_rms"]):.2f})'
def verdict(a, r):
    if float(a["max_rms"]) < float(r["min_rms"]): return "below"
    if float(a["min_rms"]) > float(r["max_rms"]): return "above"
    return "level"
head = " | ".join(f"adaptive, latency {l:g}" for l, _ in runs)
print(f"| animation | {head} | framed 60 Hz | framed 60 Hz + TAA |")
print("|---|" + "---:|" * (len(runs) + 2))
anims = [a for (a, m) in b if m == "framed-60hz"]
for anim in anims:
    f60, taa = b[(anim, "framed-60hz")], b[(anim, "framed-taa")]
    row = []
    for _, c in runs:
        a = c[(anim, "adaptive")]
        row.append(f"{show(a)}; {verdict(a, f60)} / {verdict(a, taa)}")
    print(f"| {anim} | " + " | ".join(row) + f" | {show(f60)} | {show(taa)} |")
print()
print("Each adaptive cell: mean (range) over the seeds; below / above / level against framed "
      "60 Hz, then against framed 60 Hz + TAA, beyond the spread.")
PY
}

# seed_means LABEL DIR...: the mean and range over the seeds of mean_rms in the DIRs'
# sweep.csv, per knob value and animation, as a markdown table.
seed_means() {
  local label=$1
  shift
  python3 - "$label" "$@" <<'PY'
import csv, statistics, sys
label, dirs = sys.argv[1], sys.argv[2:]
runs = {}  # (value, animation) -> [mean_rms per seed]
order = []
for d in dirs:
    with open(f"{d}/sweep.csv") as f:
        for row in csv.DictReader(f):
            key = (row["value"], row["animation"])
            if row["value"] not in order:
                order.append(row["value"])
            runs.setdefault(key, []).append(float(row["mean_rms"]))
animations = [a for a in ("bart", "toycar", "interactive", "builtin")
              if any(k[1] == a for k in runs)]
print(f"### {label}\n")
print("| value | " + " | ".join(animations) + " | mean of the animations |")
print("|---|" + "---:|" * (len(animations) + 1))
for value in order:
    cells, means = [], []
    for a in animations:
        v = runs.get((value, a))
        if not v:
            cells.append("")
            continue
        m = statistics.mean(v)
        means.append(m)
        cells.append(f"{m:.2f} ({min(v):.1f}-{max(v):.1f})")
    total = f"{statistics.mean(means):.2f}" if len(means) == len(animations) else ""
    print(f"| {value} | " + " | ".join(cells) + f" | {total} |")
print()
PY
}

usage() { sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; }

list() {
  local n
  for n in "${names[@]}"; do
    local note=""
    [ "${FLAGS[$n]}" = root ] && note=" (needs root)"
    [ "${FLAGS[$n]}" = self ] && note=" (the command writes it)"
    printf '%s -> %s%s\n' "$n" "$(realpath -m --relative-to=. "bench/results/${FILE[$n]}")" "$note"
    printf '    %s\n' "${CMD[$n]//\$BUILD/$BUILD}"
  done
  echo "Recorded by hand, not run here: test-times.md, still-scene-reconstruction.md (bench/results/README.md)."
}

run_one() {
  local n=$1 out=bench/results/${FILE[$1]} body commit dirty load
  if [ "${FLAGS[$n]}" = root ] && [ "$(id -u)" -ne 0 ]; then
    echo "refresh_results.sh: $n needs root (network namespaces): skipped" >&2
    return 2
  fi
  commit=$(git rev-parse --short HEAD)
  dirty=$(git status --porcelain --untracked-files=no | head -1)
  load=$(cut -d' ' -f1-3 /proc/loadavg)
  echo "== $n: ${CMD[$n]//\$BUILD/$BUILD}" >&2
  if [ "${FLAGS[$n]}" = self ]; then
    (eval "${CMD[$n]}") || return 1
    return 0
  fi
  body=$(mktemp)
  if ! (eval "${CMD[$n]}") >"$body"; then
    rm -f "$body"
    return 1
  fi
  {
    echo "# ${TITLE[$n]}"
    echo
    echo "${WHAT[$n]}"
    echo
    echo "- Command: \`${CMD[$n]//\$BUILD/$BUILD}\`"
    echo "- Generated by \`bench/refresh_results.sh $n\` at commit $commit${dirty:+ (with uncommitted changes)}," \
      "$(date -u +%Y-%m-%d), on $(nproc) cores, load average $load at the start; build folder $BUILD."
    echo
    cat "$body"
  } >"$out.tmp"
  mv "$out.tmp" "$out"
  rm -f "$body"
}

wanted=() list_only=0
while [ $# -gt 0 ]; do
  case "$1" in
    --list) list_only=1; shift ;;
    --build) BUILD=$2; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    all) wanted+=("${names[@]}"); shift ;;
    -*) echo "refresh_results.sh: unknown option '$1'" >&2; exit 2 ;;
    *)
      [ -n "${FILE[$1]+x}" ] || { echo "refresh_results.sh: unknown result '$1' (--list names them)" >&2; exit 2; }
      wanted+=("$1"); shift ;;
  esac
done
if [ $list_only = 1 ]; then
  list
  exit 0
fi
if [ ${#wanted[@]} -eq 0 ]; then
  usage
  exit 2
fi
export BUILD
status=0
for n in "${wanted[@]}"; do
  if run_one "$n"; then
    echo "== $n: $(realpath -m --relative-to=. "bench/results/${FILE[$n]}") written" >&2
  else
    rc=$?
    [ $rc -eq 2 ] || { echo "== $n: FAILED, bench/results/${FILE[$n]} left as it was" >&2; status=1; }
  fi
done
exit $status
