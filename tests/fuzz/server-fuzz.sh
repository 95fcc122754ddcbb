#!/usr/bin/env bash
# The longer fuzz run against a real server: builds cinevol-server-fuzz (and
# the server and reader) in build/, then runs it niced: a cinevol-server on a
# free loopback port (CPU backend, a small data root, --max-volume-memory-mb 64
# --max-upload-memory-mb 64), a witness session that must keep streaming, the
# fuzz corpora as they are and then mutated inputs (uploads of NIfTI, NRRD,
# MetaImage and VTK; DICOM series of 1 to 3 slices loaded from the data
# root), bounded in count and time. Prints and keeps report.txt: inputs,
# outcomes (loaded / refused by code / reader stopped by signal or limit),
# server deaths (must be 0), witness frames. Exits non-zero on a death or a
# witness that stopped streaming.
#
#   tests/fuzz/server-fuzz.sh [SECONDS] [INPUTS]          # default 600 s, 100000 inputs
#   PRECHECKS=off tests/fuzz/server-fuzz.sh 120 0         # the corpus only, pre-checks off in the server
#   SEED=7 OUT=/tmp/run tests/fuzz/server-fuzz.sh 2400    # another seed, the results kept there
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-600}
inputs=${2:-100000}
build=${BUILD_DIR:-build}
out=${OUT:-$(mktemp -d "${TMPDIR:-/tmp}/cinevol-server-fuzz-XXXXXX")}
[ -f "$build/build.ninja" ] || { echo "configure $build first (README: scripts/test.sh)"; exit 1; }
cmake --build "$build" --target cinevol-server-fuzz cinevol-server cinevol-reader | { grep -vE '^\[[0-9]+/[0-9]+\] ' || true; }

args=(--server "$build/cinevol-server" --corpus tests/fuzz/corpus --out "$out" --seconds "$seconds"
      --inputs "$inputs" --seed "${SEED:-1}" --prechecks "${PRECHECKS:-on}")
[ "$inputs" = 0 ] && args+=(--replay-only)
echo "server fuzz: ${seconds} s, at most ${inputs} mutated inputs, pre-checks ${PRECHECKS:-on}, results in $out"
echo "machine: $(nproc) cores, $(sed -nE 's/^model name\s*: //p' /proc/cpuinfo | head -1)"
rc=0
nice -n 10 "$build/cinevol-server-fuzz" "${args[@]}" || rc=$?
exit $rc
