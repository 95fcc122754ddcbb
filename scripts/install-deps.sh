#!/usr/bin/env bash
# Installs the Debian packages cinevol builds against. Idempotent: installs
# only what is missing, so a second run costs a dpkg query and nothing else.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libinsighttoolkit5-dev        # volume I/O: NIfTI, NRRD, MetaImage, VTK, DICOM (GDCM, JPEG 2000)
  libprotobuf-dev protobuf-compiler
  libgrpc++-dev protobuf-compiler-grpc
  libjpeg62-turbo-dev libpng-dev libopenexr-dev
  libspdlog-dev libcli11-dev
  libgtest-dev libgmock-dev
  libturbojpeg0-dev             # tests: TurboJPEG's YCbCr planes, the display's reference
  clang libclang-rt-14-dev      # tests/fuzz: clang 14 with libFuzzer, ASan and UBSan
  prometheus-cpp-dev            # the server's /metrics (--metrics-listen)
  prometheus                    # promtool, which the metrics test checks the exposition with
  openssl                       # the TLS tests make their own CA and certificates
  libseccomp-dev                # cinevol-reader: the system calls a reader may make
  libsdl2-dev libimgui-dev      # cinevol-viewer: the window and its panels
  xvfb xauth                    # the viewer's tests run it on a virtual display
  python3-yaml yamllint         # tests/deploy: the Kubernetes and Compose manifests' checks
  libcurl4-openssl-dev          # server/pacs: DICOMweb (QIDO-RS, WADO-RS, STOW-RS) over HTTP and HTTPS
  libdcmtk-dev                  # cinevol-reader: DICOM SEG (dcmdata); the tests write SEGs with dcmseg; server/pacs: SR measurement reports written with dcmsr
  libavcodec-dev libavformat-dev libswscale-dev libavutil-dev   # server/video: movies as H.264 (libx264) in MP4
  ffmpeg                        # tests: ffprobe counts a movie's frames
  liblcms2-dev                  # server/pacs: the sRGB ICC profile a presentation state's output colours are in
  orthanc orthanc-dicomweb      # tests/pacs: a real PACS with its DICOMweb plugin, started by the tests
  dcmtk dicom3tools             # tests/pacs: DCMTK's dcmdump/dcm2pnm and dciodvfy check every object cinevol writes
  chromium                      # web/e2e: the page tested in a real headless browser
  podman runc mmdebstrap        # scripts/images.sh: the images built and run (docs/deploy.md); no registry: a Debian base made here
  netavark aardvark-dns         # the stack's containers find one another by name (podman's network backend and its DNS)
  iptables                      # netavark runs it to set up the containers' network (it does not depend on it)
  podman-compose                # deploy/compose run by podman (tests/containers)
  catatonit                     # the pause process of the pods `podman kube play` makes (tests/containers)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# tests/deploy validates the manifests against the Kubernetes schemas with an npm
# package; a node and npm from elsewhere (NodeSource bundles npm) serve as well.
command -v npm >/dev/null || missing+=(nodejs npm)

if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -q
  $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# web/: the page's and cinevol-web's npm packages, exactly as the lockfile
# pins them (no browser download: the tests drive Debian's chromium). Again
# only when the lockfile changed since the last install.
web="$(dirname "$0")/../web"
if ! cmp -s "$web/package-lock.json" "$web/node_modules/.cinevol-installed-lock" 2>/dev/null; then
  echo "installing web/'s npm packages (npm ci)"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
  cp "$web/package-lock.json" "$web/node_modules/.cinevol-installed-lock"
fi
