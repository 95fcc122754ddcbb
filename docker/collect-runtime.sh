#!/usr/bin/env bash
# Copies built programs and the shared libraries they load into one folder, for
# an image's final stage: OUT/bin and OUT/lib. glibc's own libraries stay out
# (the runtime base has them), and so does libcuda (the NVIDIA container
# toolkit mounts the host driver's).
#
#   docker/collect-runtime.sh OUT PROGRAM...
set -euo pipefail
[ $# -ge 2 ] || { echo "usage: $0 OUT PROGRAM..." >&2; exit 2; }
out=$1; shift
mkdir -p "$out/bin" "$out/lib"
skip='/(libc|libm|libpthread|libdl|librt|ld-linux[^/]*|libcuda)\.so'
for program in "$@"; do
  cp -L "$program" "$out/bin/"
  ldd "$program" | awk '/=> \//{print $3}' | grep -vE "$skip" | while read -r lib; do
    [ -e "$out/lib/$(basename "$lib")" ] || cp -L "$lib" "$out/lib/"
  done
done
strip --strip-unneeded "$out"/bin/* "$out"/lib/*.so* 2>/dev/null || true
