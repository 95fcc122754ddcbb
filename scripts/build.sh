#!/usr/bin/env bash
# Configures the build folder (once) and builds cinevol in it: every target,
# or only the targets given as arguments (scripts/demo.sh names what the demo
# runs). The folder is build/, or $CINEVOL_BUILD_DIR.
#
# CUDA backends, decided when the folder is configured (CINEVOL_CUDA):
#   AUTO  whenever nvcc is found, GPU or not: CUDA code keeps compiling (the test command)
#   GPU   only where nvcc can build for a GPU this machine has (the demo's default)
#   ON    always (an error without nvcc); OFF: never
# Unset, a new folder takes $CINEVOL_CUDA_DEFAULT (AUTO when that is unset too)
# and a configured one stays as it is; set, it configures the folder again
# where its setting differs.
# CINEVOL_BUILD_DRY_RUN=1 prints the cmake commands instead (tests/scripts).
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${CINEVOL_BUILD_DIR:-build}"

run() {
  if [ "${CINEVOL_BUILD_DRY_RUN:-0}" = 1 ]; then echo "$*"; else "$@"; fi
}

# The compute capability ("86") of this machine's first GPU, when nvcc can
# build code for it; nothing when there is no nvcc, no GPU or no driver.
usable_gpu() {
  local nvcc cap
  nvcc=$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)
  [ -x "$nvcc" ] && command -v nvidia-smi > /dev/null || return 0
  cap=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2> /dev/null | head -1 | tr -d '. \r') || return 0
  if [ -n "$cap" ] && "$nvcc" --list-gpu-code 2> /dev/null | grep -qx "sm_$cap"; then echo "$cap"; fi
}

# The CMake arguments for a CUDA choice: GPU becomes ON (for that GPU) or OFF.
cuda_arguments() {
  local cap
  if [ "$1" != GPU ]; then
    echo "-DCINEVOL_CUDA=$1"
  elif cap=$(usable_gpu) && [ -n "$cap" ]; then
    echo "-DCINEVOL_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=$cap"
  else
    echo "-DCINEVOL_CUDA=OFF"
  fi
}

configure() {
  local arguments
  arguments=$(cuda_arguments "$1")
  echo "cinevol: configuring $dir ($arguments)" >&2
  # shellcheck disable=SC2086  # the arguments are words
  run cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release $arguments
}

if [ ! -f "$dir/build.ninja" ]; then
  configure "${CINEVOL_CUDA:-${CINEVOL_CUDA_DEFAULT:-AUTO}}"
elif [ -n "${CINEVOL_CUDA:-}" ]; then
  wanted=$(cuda_arguments "$CINEVOL_CUDA" | sed 's/^-DCINEVOL_CUDA=\([A-Z]*\).*/\1/')
  held=$(sed -n 's/^CINEVOL_CUDA:STRING=//p' "$dir/CMakeCache.txt")
  [ "$wanted" = "$held" ] || configure "$CINEVOL_CUDA"
fi
run cmake --build "$dir" -j "$(nproc)" ${1:+--target "$@"}
