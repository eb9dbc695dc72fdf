#!/usr/bin/env bash
# Packs built afr programs with the shared libraries they load into one folder that runs on
# another x86-64 Linux machine without afr's build dependencies (a GPU server, say):
#
#   deploy/bundle.sh DEST PROGRAM...     e.g. deploy/bundle.sh /tmp/afr build/bench/afr-bench-reconstruct
#   DEST/run afr-bench-reconstruct --backends gl ...
#
# Left out: the C and C++ runtimes and the dynamic loader (the target's own, which must be as new as
# this machine's: glibc 2.36 for Debian 12), and OpenGL/EGL/Vulkan (libEGL, libGL*, glvnd's
# dispatch, libvulkan): those must come from the target, whose driver they load. Programs
# that link OpenImageIO bring hundreds of megabytes with it; afr-bench-reconstruct does not.
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: deploy/bundle.sh DEST PROGRAM..." >&2
  exit 2
fi
dest=$1
shift
mkdir -p "$dest/bin" "$dest/lib"
skip='^(libc|libm|libdl|libpthread|librt|libresolv|libstdc\+\+|libgcc_s|ld-linux-x86-64|linux-vdso|libEGL|libGL|libGLX|libGLdispatch|libOpenGL|libGLESv2|libvulkan|libgbm|libdrm)\.so'
for program in "$@"; do
  [ -x "$program" ] || { echo "bundle.sh: $program is not an executable" >&2; exit 2; }
  cp "$program" "$dest/bin/"
  ldd "$program" | awk '$2 == "=>" && $3 ~ /^\// {print $3}' | while read -r lib; do
    name=$(basename "$lib")
    if [[ ! "$name" =~ $skip ]]; then cp -L "$lib" "$dest/lib/$name"; fi
  done
done
# The commit the programs were built from, for the results they give (bench/gpu.sh --bin).
commit=$(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)
git -C "$(dirname "$0")" status --porcelain 2>/dev/null | grep -qv '^??' && commit+=" with uncommitted changes"
echo "$commit" >"$dest/COMMIT"
cat >"$dest/run" <<'EOF'
#!/usr/bin/env bash
# Runs a bundled program with the bundle's libraries: run PROGRAM [ARGS...]
here=$(cd "$(dirname "$0")" && pwd)
program=$1
shift
LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" exec "$here/bin/$program" "$@"
EOF
chmod +x "$dest/run"
echo "bundle.sh: $(ls "$dest/bin" | wc -l) programs, $(ls "$dest/lib" | wc -l) libraries," \
  "$(du -sh "$dest" | cut -f1) in $dest"
