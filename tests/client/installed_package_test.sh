#!/usr/bin/env bash
# The installed client package works for a program of one's own: install the
# build, build examples/client-app against it with find_package(cinevol), run
# it against a real local server (a free loopback port; stopped by its pid).
#   installed_package_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 source=$2
. "$source/scripts/wait-for-port.sh"
work=$(mktemp -d)
server=
cleanup() {
  [ -n "$server" ] && kill "$server" 2>/dev/null && wait "$server" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
cmake -S "$source/examples/client-app" -B "$work/app" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" > "$work/configure.log"
cmake --build "$work/app" > "$work/build.log"
"$work/prefix/bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$work/port" --backend cpu \
  --volume 'phantom:head?size=48' > "$work/server.log" 2>&1 &
server=$!
wait_for_port "$work/port" $server 30 "$work/server.log"
timeout 60 "$work/app/cinevol-client-app" "127.0.0.1:$(cat "$work/port")" "$work/out"
test -s "$work/out/refined.jpg" && test -s "$work/out/still.png"
echo "installed package: built and ran examples/client-app"
