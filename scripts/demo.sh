#!/usr/bin/env bash
# README command 1: install, build, then run `cinevol demo` on the built-in phantom.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
exec build/cinevol demo "$@"
