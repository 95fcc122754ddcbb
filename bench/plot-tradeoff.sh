#!/usr/bin/env bash
# Installs matplotlib from Debian (idempotent) and plots a tradeoff run:
#   bench/plot-tradeoff.sh RESULTS_DIR
set -euo pipefail
if ! /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get install -y -q --no-install-recommends python3-matplotlib
fi
exec /usr/bin/python3 "$(dirname "$0")/plot_tradeoff.py" "$@"
