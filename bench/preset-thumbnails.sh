#!/usr/bin/env bash
# The thumbnails of docs/presets.md: a local cinevol-server over the shared
# data, `cinevol volumes load`, then `cinevol snapshot` of each preset on a
# data set it suits, and of every data set with its default preset.
#   bash bench/preset-thumbnails.sh            # CPU, about 10 minutes on a busy 2-core machine
#   BIN=/tmp/cv/bin BACKEND=cuda SPP=1024 bash bench/preset-thumbnails.sh
#   DATASETS="mr-chest-dicom-seg3d" bash bench/preset-thumbnails.sh   # only these (paths under DATA)
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
bin=${BIN:-build}
data=${DATA:-../shared/data}
out=${OUT:-docs/presets}
size=${SIZE:-256}
spp=${SPP:-64}
mkdir -p "$out"
port_file=$(mktemp)
log=${LOG:-$(mktemp --suffix=.log)}  # the server's log, kept out of the docs
# A still on a busy CPU can take longer than the 15 s a session may wait
# for its first stream before the server reaps it (issue 32, item 1).
"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --data-root "$data" \
  --backend "${BACKEND:-auto}" --unattached-session-seconds 3600 > "$log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; rm -f "$port_file"' EXIT
# The server makes its built-in phantom first: on a busy 2-core machine that
# takes well over 10 s.
wait_for_port "$port_file" $server 120 "$log"
address=127.0.0.1:$(cat "$port_file")

# load PATH: loads a data set and prints its id.
load() {
  "$bin/cinevol" volumes load "$1" --server "$address" --json |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["id"])'
}

# shoot VOLUME_ID NAME [PRESET]: one still; no preset: the volume's default.
shoot() {
  local preset=()
  [ -n "${3:-}" ] && preset=(--preset "$3")
  "$bin/cinevol" snapshot --server "$address" --volume "$1" "${preset[@]}" --width "$size" --height "$size" \
    --spp "$spp" --out "$out/$2.png"
}

declare -A presets=(
  [ct-body-totalsegmentator/aorta_ct_cropped.nii.gz]="ct-bone ct-soft-tissue ct-vessels ct-aaa ct-cardiac ct-coronary ct-chest-contrast ct-muscle ct-mip"
  [ct-body-totalsegmentator/pulmonary_ct_cropped.nii.gz]="ct-lung ct-pulmonary-arteries"
  [mr-head-seg3d-nifti/MR.nii.gz]="mr-default mr-t2-brain mr-mip mr-angio"
  [ct-head-cthead/DERIVED_CThead.nhdr]="ct-auto"
  [ct-objects-openscivis/bonsai.nii.gz]="auto"
)
default_datasets=(ct-body-totalsegmentator/aorta_ct_cropped.nii.gz ct-body-totalsegmentator/pulmonary_ct_cropped.nii.gz
  ct-body-totalsegmentator/example_ct.nii.gz ct-body-totalsegmentator/example_ct_dicom ct-chest-lidc2/LIDC2.nhdr
  ct-head-avm/CT_AVM.nii.gz ct-head-cthead/DERIVED_CThead.nhdr ct-head-headsq/quarter.nhdr
  ct-objects-openscivis/bonsai.nii.gz ct-objects-openscivis/engine.nii.gz mr-chest-dicom-seg3d mr-head-seg3d-nifti/MR.nii.gz)
read -r -a datasets <<< "${DATASETS:-${default_datasets[*]}}"
for path in "${datasets[@]}"; do
  id=$(load "$path")
  shoot "$id" "default--$(basename "${path%%.*}")"
  for preset in ${presets[$path]:-}; do shoot "$id" "$preset" "$preset"; done
done
