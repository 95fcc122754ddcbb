# A stand-in PACS for the one-node stack (deploy/compose): Debian's Orthanc with
# its DICOMweb plugin, the version the PACS tests run (docs/pacs.md). No DICOM
# port; HTTP on 8042 (REST and /dicom-web/), every call authenticated: the users
# come from a file the stack mounts at /etc/cinevol-orthanc/users.json
# ({"RegisteredUsers": {"NAME": "PASSWORD"}}). Storage in /var/lib/orthanc/db (a
# named volume in the stack). Runs as Debian's orthanc user; no writable root.
#
#   podman build --format docker -f docker/stack/orthanc.Dockerfile -t cinevol-orthanc .

ARG RUNTIME_BASE=debian:bookworm-slim
FROM ${RUNTIME_BASE}
RUN apt-get update -q \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends orthanc orthanc-dicomweb \
 && rm -rf /var/lib/apt/lists/* \
 && install -d -o orthanc -g orthanc /var/lib/orthanc/db
COPY docker/stack/orthanc.json /etc/cinevol-orthanc/orthanc.json
USER orthanc
EXPOSE 8042
# Up when its HTTP port answers (every path asks for credentials, the health check has none).
HEALTHCHECK --interval=10s --timeout=5s --start-period=20s \
  CMD ["/bin/bash", "-c", "exec 3<>/dev/tcp/127.0.0.1/8042 && printf 'GET /system HTTP/1.0\\r\\n\\r\\n' >&3 && head -c 12 <&3 | grep -q '^HTTP/1.[01] '"]
STOPSIGNAL SIGTERM
ENTRYPOINT ["/usr/sbin/Orthanc"]
CMD ["/etc/cinevol-orthanc/"]
