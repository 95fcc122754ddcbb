# shellcheck shell=bash disable=SC2154,SC2034  # the caller gives bin, work, series; uses url
# Sourced by the PACS benches (bench/pacs-run.sh, bench/rendered-run.sh): a scratch folder ($work) and the list of
# processes started (pids), both cleaned up on exit; then Debian's Orthanc with its DICOMweb plugin on a free
# loopback port of its own, seeded with stamped copies of a shared DICOM series (one study and series, an instance
# UID per file, as the shared series lack them). Needs $bin (the build) and $series (the folder of DICOM files);
# sets work, pids, port, url, study, uid and instances.
work=$(mktemp -d /tmp/cinevol-bench.XXXXXX)
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2> /dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
now() { date +%s.%N; }
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }

study=2.25.77000001 uid=2.25.77000001.1
mkdir -p "$work/series"
instances=0
for f in "$series"/*; do
  case "$f" in *README* | *.txt | *.md) continue ;; esac
  instances=$((instances + 1))
  cp "$f" "$work/series/$instances.dcm"
  dcmodify -nb -q -i "(0020,000d)=$study" -i "(0020,000e)=$uid" -i "(0008,0018)=$uid.$instances" \
    -i "(0010,0020)=CINEVOL-BENCH" "$work/series/$instances.dcm"
done

port=$(free_port)
cat > "$work/orthanc.json" << JSON
{ "Name": "cinevol-bench", "HttpPort": $port, "DicomServerEnabled": false, "RemoteAccessAllowed": false,
  "AuthenticationEnabled": false, "StorageDirectory": "$work/storage", "IndexDirectory": "$work/storage",
  "Plugins": ["/usr/share/orthanc/plugins/libOrthancDicomWeb.so"], "DicomWeb": {"Enable": true, "Root": "/dicom-web/"} }
JSON
LD_PRELOAD=$PWD/$bin/tests/libcinevol_loopback_bind.so Orthanc "$work/orthanc.json" > "$work/orthanc.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do curl -sf "http://127.0.0.1:$port/system" > /dev/null && break; sleep 0.1; done
for f in "$work"/series/*.dcm; do
  curl -sf -X POST --data-binary @"$f" "http://127.0.0.1:$port/instances" > /dev/null
done
url="http://127.0.0.1:$port/dicom-web"
