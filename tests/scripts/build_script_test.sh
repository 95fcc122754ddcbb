#!/usr/bin/env bash
# scripts/build.sh's choices, as cmake commands (CINEVOL_BUILD_DRY_RUN=1),
# on a machine faked with nvcc and nvidia-smi of our own: the demo builds its
# three programs only, with CUDA only for a GPU nvcc can build for (or when
# asked); the test command builds everything, with CUDA wherever nvcc is.
set -euo pipefail
source_dir=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0

# A fake nvcc that builds for sm_80 and sm_90, and nvidia-smi reporting a GPU
# of compute capability `cap` (none: failing, as it does without a driver).
fake_machine() {
  local cap=$1
  rm -rf "${work:?}/bin" && mkdir -p "$work/bin"
  printf '#!/bin/sh\nprintf "sm_80\\nsm_90\\n"\n' > "$work/bin/nvcc"
  if [ -n "$cap" ]; then
    printf '#!/bin/sh\necho %s\n' "$cap" > "$work/bin/nvidia-smi"
  else
    printf '#!/bin/sh\necho "NVIDIA-SMI has failed" >&2\nexit 9\n' > "$work/bin/nvidia-smi"
  fi
  chmod +x "$work"/bin/*
}

# Runs build.sh in the fake machine on build folder $work/b; prints its commands.
build() {
  env PATH="$work/bin:$PATH" CINEVOL_BUILD_DRY_RUN=1 CINEVOL_BUILD_DIR="$work/b" "$@" \
    bash "$source_dir/scripts/build.sh" "${targets[@]}" 2> /dev/null
}

expect() {  # expect WHAT OUTPUT PATTERN: OUTPUT matches the extended regex PATTERN
  if ! grep -Eq -- "$3" <<< "$2"; then
    echo "FAILED: $1: wanted /$3/ in:"; echo "$2"; failures=$((failures + 1))
  fi
}
refuse() {  # refuse WHAT OUTPUT PATTERN: OUTPUT does not match PATTERN
  if grep -Eq -- "$3" <<< "$2"; then
    echo "FAILED: $1: did not want /$3/ in:"; echo "$2"; failures=$((failures + 1))
  fi
}

demo=(cinevol-server cinevol cinevol-reader)

# The demo on a machine without a GPU: no CUDA, its three programs only.
fake_machine ""
targets=("${demo[@]}")
out=$(build CINEVOL_CUDA_DEFAULT=GPU)
expect "demo, no GPU" "$out" "-DCINEVOL_CUDA=OFF"
expect "demo, no GPU" "$out" "--target cinevol-server cinevol cinevol-reader$"

# The demo where nvcc builds for the GPU: CUDA for that GPU.
fake_machine "9.0"
out=$(build CINEVOL_CUDA_DEFAULT=GPU)
expect "demo, H100" "$out" "-DCINEVOL_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=90"

# A GPU this nvcc cannot build for counts as none.
fake_machine "12.0"
out=$(build CINEVOL_CUDA_DEFAULT=GPU)
expect "demo, a GPU nvcc does not know" "$out" "-DCINEVOL_CUDA=OFF"

# Asked for, CUDA is built without a GPU.
fake_machine ""
out=$(build CINEVOL_CUDA_DEFAULT=GPU CINEVOL_CUDA=ON)
expect "demo, CINEVOL_CUDA=ON" "$out" "-DCINEVOL_CUDA=ON"

# The test command: every target, CUDA wherever nvcc is.
targets=()
out=$(build CINEVOL_CUDA=AUTO)
expect "tests" "$out" "-DCINEVOL_CUDA=AUTO"
refuse "tests" "$out" "--target"

# A folder the demo configured without CUDA: the test command configures it
# again; the demo, after the tests, leaves it as it is.
mkdir -p "$work/b" && touch "$work/b/build.ninja"
echo "CINEVOL_CUDA:STRING=OFF" > "$work/b/CMakeCache.txt"
out=$(build CINEVOL_CUDA=AUTO)
expect "tests after the demo" "$out" "-DCINEVOL_CUDA=AUTO"
echo "CINEVOL_CUDA:STRING=AUTO" > "$work/b/CMakeCache.txt"
targets=("${demo[@]}")
out=$(build CINEVOL_CUDA_DEFAULT=GPU)
refuse "the demo after the tests" "$out" "-DCINEVOL_CUDA"
out=$(build CINEVOL_CUDA=AUTO)
refuse "the tests again" "$out" "-DCINEVOL_CUDA"

# demo.sh asks for GPU by default and builds the demo's three programs.
expect "demo.sh" "$(cat "$source_dir/scripts/demo.sh")" \
  "CINEVOL_CUDA_DEFAULT=GPU scripts/build.sh cinevol-server cinevol cinevol-reader"

if [ "$failures" -gt 0 ]; then exit 1; fi
echo "build.sh: every choice as expected"
