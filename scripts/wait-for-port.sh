# shellcheck shell=bash
# Sourced by the scripts that start a cinevol-server or cinevol-web of their
# own (bench/*.sh, tests/client/installed_package_test.sh):
#   wait_for_port PORT_FILE PID SECONDS LOG
# returns once the process PID has written its port to PORT_FILE. When the
# process exits first (a volume that is not there, a flag it refuses) or
# SECONDS pass, it prints why and the process's LOG and exits the script with
# status 1: a run fails at once, in the server's own words, rather than after
# its timeout or with a client that cannot connect.
wait_for_port() {
  local port_file=$1 pid=$2 seconds=$3 log=$4 _
  for _ in $(seq $((seconds * 10))); do
    [ -s "$port_file" ] && return 0
    kill -0 "$pid" 2> /dev/null || break
    sleep 0.1
  done
  [ -s "$port_file" ] && return 0
  if kill -0 "$pid" 2> /dev/null; then
    echo "process $pid wrote no port to $port_file in $seconds s; its log, $log:" >&2
  else
    echo "process $pid exited before it wrote its port to $port_file; its log, $log:" >&2
  fi
  cat "$log" >&2
  exit 1
}
