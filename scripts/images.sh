#!/usr/bin/env bash
# Builds cinevol's container images with podman, from a Debian base made here
# (no image registry): the servers (CPU and CUDA), the gateway with the page,
# the client tools, and the stack's Orthanc and Prometheus. docs/deploy.md.
#
#   scripts/images.sh [--fast] [--no-cache] [--worktree | --rev REV] [IMAGE...]
#
# IMAGE: server-cpu server-gpu client web orthanc prometheus (default: all).
# --fast: the cinevol images take the build tree's programs (collected by
#   docker/collect-runtime.sh) instead of compiling them in a build stage; this
#   is what CI runs. The build tree is build/, or $CINEVOL_BUILD_DIR; it must be
#   built already (scripts/build.sh). server-gpu needs a tree built with CUDA.
# --no-cache: every layer again (timing a build from clean).
# A full build compiles the files of HEAD (git archive), so that edits under way do not
# slip into an image half made; --rev REV builds that commit instead, --worktree the
# working tree as it is.
#
# On the way it sets podman up as this kind of machine needs (idempotently:
# a drop-in in /etc/containers/containers.conf.d) and makes the Debian bases
# with mmdebstrap from the machine's own apt sources, imported as
# localhost/debian:bookworm (build stages) and localhost/debian:bookworm-slim
# (final stages: no manuals, no locales). Each base is made once: the image is
# kept, and its tar under $CINEVOL_BUILD_DIR/images/. It ends with a table of the
# images' sizes and build times (also in images/report-fast.tsv or report-full.tsv).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
build_dir=$(realpath -m "${CINEVOL_BUILD_DIR:-build}")
cache="$build_dir/images"
all_images=(server-cpu server-gpu client web orthanc prometheus)

fast=0
worktree=0
rev=HEAD
no_cache=()
images=()
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do
  a=${args[i]}
  case "$a" in
    --rev) rev=${args[++i]:-}; [[ "$rev" =~ ^[A-Za-z0-9._/-]+$ ]] || { echo "images.sh: --rev wants a commit" >&2; exit 2; } ;;
    --fast) fast=1 ;;
    --no-cache) no_cache=(--no-cache) ;;
    --worktree) worktree=1 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    server-cpu|server-gpu|client|web|orthanc|prometheus) images+=("$a") ;;
    *) echo "images.sh: unknown argument '$a' (--help)" >&2; exit 2 ;;
  esac
done
[ ${#images[@]} -gt 0 ] || images=("${all_images[@]}")

say() { echo "images.sh: $*" >&2; }
die() { say "$*"; exit 1; }

as_root() {
  if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

# --- podman as containers.md says: runc (crun cannot set rlimits here), cgroupfs (cgroups v1),
# no default ulimits, and netavark, whose DNS lets the stack's containers find one another by name.
setup_podman() {
  command -v podman > /dev/null || die "podman is not installed (scripts/install-deps.sh installs it, with mmdebstrap and runc)"
  local dropin=/etc/containers/containers.conf.d/cinevol.conf want
  want=$(cat <<'EOF'
# Written by cinevol's scripts/images.sh (shared/docs/containers.md): crun cannot set
# RLIMIT_NOFILE/RLIMIT_NPROC on machines of this kind and their cgroups are v1.
[containers]
default_ulimits = []
[engine]
cgroup_manager = "cgroupfs"
runtime = "runc"
[network]
network_backend = "netavark"
EOF
)
  if [ "$(cat "$dropin" 2> /dev/null)" != "$want" ]; then
    say "writing $dropin"
    as_root mkdir -p "$(dirname "$dropin")"
    printf '%s\n' "$want" | as_root tee "$dropin" > /dev/null
  fi
  command -v runc > /dev/null || die "runc is not installed (scripts/install-deps.sh)"
  # A bridge CNI left (podman used before this drop-in) holds netavark's subnet: ports reach nothing.
  if ip -o -4 addr show dev cni-podman0 2> /dev/null | grep -q ' 10\.88\.'; then
    say "warning: the old CNI bridge cni-podman0 holds 10.88.0.0/16, netavark's; published ports will not answer" \
        "until it goes (ip link delete cni-podman0, with no container on it)"
  fi
  [ -x /usr/lib/podman/netavark ] || command -v netavark > /dev/null ||
    die "netavark is not installed (scripts/install-deps.sh installs it with aardvark-dns)"
}

# --- The Debian bases. The apt sources are the machine's Debian ones (deb822), so that the images
# reach the same mirror; without them, deb.debian.org.
sources_file() {
  local f=/etc/apt/sources.list.d/debian.sources
  if [ -f "$f" ] && grep -q '^URIs: ' "$f"; then
    echo "$f"
  else
    f="$cache/debian.sources"
    printf '%s\n' "Types: deb" "URIs: http://deb.debian.org/debian" "Suites: bookworm bookworm-updates" \
      "Components: main" "Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg" "" \
      "Types: deb" "URIs: http://deb.debian.org/debian-security" "Suites: bookworm-security" \
      "Components: main" "Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg" > "$f"
    echo "$f"
  fi
}

ensure_base() {  # ensure_base TAG (bookworm or bookworm-slim)
  local tag=$1 image="localhost/debian:$1" tar="$cache/debian-$1.tar" sources slim=()
  if podman image exists "$image"; then return; fi
  if [ ! -s "$tar" ]; then
    command -v mmdebstrap > /dev/null || die "mmdebstrap is not installed (scripts/install-deps.sh)"
    sources=$(sources_file)
    if [ "$tag" = bookworm-slim ]; then
      # As Debian's own -slim images: no manuals, documents or translations, in this install or later ones.
      slim=(--dpkgopt='path-exclude=/usr/share/man/*' --dpkgopt='path-exclude=/usr/share/doc/*'
            --dpkgopt='path-include=/usr/share/doc/*/copyright' --dpkgopt='path-exclude=/usr/share/info/*'
            --dpkgopt='path-exclude=/usr/share/locale/*' --dpkgopt='path-include=/usr/share/locale/locale.alias')
    fi
    say "making $image with mmdebstrap (the apt sources of $sources)"
    local start=$SECONDS
    # The image's apt sources are the machine's file (the deb822 debian.sources a Debian image has);
    # the merged-usr hook merges /usr without the usrmerge package, which would bring perl (45 MB).
    mmdebstrap --quiet --variant=minbase --hook-dir=/usr/share/mmdebstrap/hooks/merged-usr "${slim[@]}" \
      --customize-hook='rm -rf "$1/etc/apt/sources.list" "$1/etc/apt/sources.list.d"; mkdir -p "$1/etc/apt/sources.list.d"' \
      --customize-hook="upload $sources /etc/apt/sources.list.d/debian.sources" \
      bookworm "${tar%.tar}.partial.tar" "$sources" > "$cache/mmdebstrap-$tag.log" 2>&1 ||
      { tail -20 "$cache/mmdebstrap-$tag.log" >&2; die "mmdebstrap failed (the log: $cache/mmdebstrap-$tag.log)"; }
    mv "${tar%.tar}.partial.tar" "$tar"
    say "made $tar in $((SECONDS - start)) s"
  fi
  podman import --quiet --change 'CMD ["/bin/bash"]' "$tar" "$image" > /dev/null
}

# --- What each image is: its Dockerfile and tag.
dockerfile_of() {
  case "$1" in
    server-cpu|server-gpu|client|web) echo "docker/$1.Dockerfile" ;;
    orthanc|prometheus) echo "docker/stack/$1.Dockerfile" ;;
  esac
}
tag_of() {
  case "$1" in
    server-cpu) echo cinevol-server:cpu ;;
    server-gpu) echo cinevol-server:gpu ;;
    *) echo "cinevol-$1:latest" ;;
  esac
}

# --fast: the context is a folder holding runtime/, the image's /opt/cinevol.
prebuilt_context() {
  local image=$1 context="$cache/context/$1" b=$build_dir
  rm -rf "$context"
  mkdir -p "$context/runtime"
  case "$image" in
    server-cpu|server-gpu)
      docker/collect-runtime.sh "$context/runtime" "$b/cinevol-server" "$b/cinevol" "$b/cinevol-reader" ;;
    client)
      local programs=("$b/cinevol" "$b/cinevol-server" "$b/cinevol-reader")
      [ -x "$b/cinevol-viewer" ] && programs+=("$b/cinevol-viewer")
      docker/collect-runtime.sh "$context/runtime" "${programs[@]}" ;;
    web)
      mkdir -p "$context/runtime/bin/web"
      cp -r "$b/web/gateway.mjs" "$b/web/static" "$context/runtime/bin/web/"
      cp "$b/cinevol-web" "$context/runtime/bin/" ;;
  esac
  echo "$context"
}

check_build_tree() {
  local image=$1 p
  case "$image" in
    server-cpu|server-gpu|client) for p in cinevol-server cinevol cinevol-reader; do
        [ -x "$build_dir/$p" ] || die "--fast: $build_dir/$p is not built (scripts/build.sh)"; done ;;
    web) [ -f "$build_dir/web/gateway.mjs" ] && [ -x "$build_dir/cinevol-web" ] ||
           die "--fast: $build_dir/cinevol-web is not built (scripts/build.sh web)" ;;
  esac
  if [ "$image" = server-gpu ] && ! ldd "$build_dir/cinevol-server" | grep -q libcudart; then
    die "--fast: $build_dir/cinevol-server was built without CUDA: no server-gpu image from it"
  fi
}

# The context of a full build: HEAD's files, exported once per commit, or the working tree.
source_context() {
  local dir="$cache/context/source" commit
  if [ "$worktree" = 1 ]; then
    echo "$root"
    return
  fi
  commit=$(git -C "$root" rev-parse --verify -q "$rev^{commit}" 2> /dev/null) ||
    { [ "$rev" = HEAD ] && { echo "$root"; return; }; die "--rev $rev: no such commit"; }
  if [ "$(cat "$dir.rev" 2> /dev/null)" != "$commit" ]; then
    rm -rf "$dir"
    mkdir -p "$dir"
    git -C "$root" archive --format=tar "$commit" | tar -x -C "$dir"
    echo "$commit" > "$dir.rev"
  fi
  if [ "$rev" = HEAD ] && [ -n "$(git -C "$root" status --porcelain --untracked-files=no 2> /dev/null)" ]; then
    say "building HEAD (${commit:0:12}): the working tree's uncommitted changes are not in the images (--worktree)"
  fi
  echo "$dir"
}

build_one() {
  local image=$1 dockerfile tag context args start
  dockerfile=$(dockerfile_of "$image")
  tag=$(tag_of "$image")
  args=(--format docker --network host --pull=never --layers "${no_cache[@]}"
        --build-arg BASE=localhost/debian:bookworm --build-arg RUNTIME_BASE=localhost/debian:bookworm-slim)
  context=$root
  [ "$fast" = 1 ] || context=$full_context
  if [[ "$image" != orthanc && "$image" != prometheus ]]; then
    if [ "$fast" = 1 ]; then
      check_build_tree "$image"
      context=$(prebuilt_context "$image")
      args+=(--build-arg PROGRAMS_FROM=prebuilt)
    else
      # Said even though it is the default: podman skips the stages no build argument names.
      args+=(--build-arg PROGRAMS_FROM=build)
      # Where this host's node trusts an extra CA (a proxy that inspects TLS), the build stage's
      # npm ci is given the same file, mounted for the build only: no layer keeps it.
      if [ -n "${NODE_EXTRA_CA_CERTS:-}" ] && [ -f "$NODE_EXTRA_CA_CERTS" ]; then
        args+=(--volume "$NODE_EXTRA_CA_CERTS:/run/cinevol-build-ca.crt:ro"
               --build-arg NODE_EXTRA_CA_CERTS=/run/cinevol-build-ca.crt)
      fi
    fi
  fi
  say "building $tag ($dockerfile$([ "$fast" = 1 ] && echo ', --fast'))"
  start=$SECONDS
  podman build "${args[@]}" -f "$([ "$fast" = 1 ] && echo "$root" || echo "$context")/$dockerfile" -t "$tag" "$context" > "$cache/build-$image-$mode.log" 2>&1 ||
    { tail -30 "$cache/build-$image-$mode.log" >&2; die "building $tag failed (the log: $cache/build-$image-$mode.log)"; }
  printf '%s\t%s\t%s\t%s\n' "$image" "$tag" "$(podman image inspect --format '{{.Size}}' "$tag")" \
    "$((SECONDS - start))" >> "$report"
}

mode=$([ "$fast" = 1 ] && echo fast || echo full)
report="$cache/report-$mode.tsv"
mkdir -p "$cache"
setup_podman
ensure_base bookworm-slim
for image in "${images[@]}"; do
  # Only the compiling build stages start from the full base.
  if [ "$fast" = 0 ] && [[ "$image" != orthanc && "$image" != prometheus ]]; then ensure_base bookworm; fi
done
# One export for the whole run: a commit made meanwhile does not change the images' sources.
[ "$fast" = 1 ] || full_context=$(source_context)
: > "$report"
for image in "${images[@]}"; do build_one "$image"; done
echo "image                     size      built in ($mode$([ ${#no_cache[@]} -gt 0 ] && echo ', no cache'))"
while IFS=$'\t' read -r _ tag bytes seconds; do
  printf '%-25s %5d MB  %4d s\n' "$tag" "$((bytes / 1000000))" "$seconds"
done < "$report"
