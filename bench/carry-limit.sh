# shellcheck shell=bash
# Sourced by the bundle scripts: the device tool carries the working tree and
# the named folders, 64 MiB in all. check_carry FOLDER fails, naming the
# sizes, where FOLDER and the tracked files would not fit one call.
carry_limit_bytes=$((64 * 1024 * 1024))

check_carry() {
  local folder=$1 tree bundle
  tree=$(git ls-files -z | xargs -0 du -cb 2>/dev/null | tail -1 | cut -f1)
  bundle=$(du -sb "$folder" | cut -f1)
  if [ $((tree + bundle)) -gt "$carry_limit_bytes" ]; then
    echo "$folder: $((bundle >> 20)) MiB with the working tree's $((tree >> 20)) MiB is over the" \
      "device tool's 64 MiB carry: pack fewer programs (PROGRAMS=, NO_DICOM=1), or" \
      "bench/make-speed-bundle.sh, which spreads the libraries over calls" >&2
    return 1
  fi
}
