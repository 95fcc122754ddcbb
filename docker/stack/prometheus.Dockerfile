# Prometheus for the one-node stack (deploy/compose): Debian's package, so that
# no registry is needed. The stack mounts its configuration (prometheus.yml) and
# the alert rules (alerts.yml) from deploy/compose; the data lives in /prometheus
# (a named volume). Runs as Debian's prometheus user; no writable root.
#
#   podman build --format docker -f docker/stack/prometheus.Dockerfile -t cinevol-prometheus .

ARG RUNTIME_BASE=debian:bookworm-slim
FROM ${RUNTIME_BASE}
RUN apt-get update -q \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends prometheus \
 && rm -rf /var/lib/apt/lists/* \
 && install -d -o prometheus -g prometheus /prometheus
USER prometheus
EXPOSE 9090
HEALTHCHECK --interval=10s --timeout=5s --start-period=20s \
  CMD ["/bin/bash", "-c", "exec 3<>/dev/tcp/127.0.0.1/9090 && printf 'GET /-/ready HTTP/1.0\\r\\n\\r\\n' >&3 && head -c 15 <&3 | grep -q ' 200'"]
STOPSIGNAL SIGTERM
ENTRYPOINT ["/usr/bin/prometheus"]
CMD ["--config.file=/etc/prometheus/prometheus.yml", "--storage.tsdb.path=/prometheus", \
     "--web.listen-address=0.0.0.0:9090", "--storage.tsdb.retention.time=15d"]
