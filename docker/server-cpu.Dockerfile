# The CPU server image: cinevol-server rendering on every core (no GPU), and
# the `cinevol` CLI (its health check). Two ways to fill /opt/cinevol:
#   PROGRAMS_FROM=build     (default) a Debian stage builds them with the README's
#                           scripts (scripts/install-deps.sh, scripts/build.sh);
#   PROGRAMS_FROM=prebuilt  the context's runtime/ folder holds them already, as
#                           docker/collect-runtime.sh leaves them (scripts/images.sh
#                           --fast: the build tree's programs, nothing compiled here).
# The final stage holds only the programs and the libraries they load, runs as
# uid 10001 and needs no writable root (a tmpfs at /tmp). docs/deploy.md.
#
#   docker build -f docker/server-cpu.Dockerfile -t cinevol-server:cpu .
#   docker run -p 127.0.0.1:50051:50051 --read-only --tmpfs /tmp -v "$PWD/secrets:/etc/cinevol:ro" \
#     -v /data/ct:/data:ro cinevol-server:cpu
#   scripts/images.sh          # the same with podman, from a Debian base made here (no registry)

ARG BASE=debian:bookworm
ARG RUNTIME_BASE=debian:bookworm-slim
ARG PROGRAMS_FROM=build

FROM ${BASE} AS build
WORKDIR /src
COPY scripts/install-deps.sh scripts/
COPY web/package.json web/package-lock.json web/
# npm ci of web/ behind a TLS-inspecting proxy: its CA, mounted for the build only (scripts/images.sh).
ARG NODE_EXTRA_CA_CERTS
RUN scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
COPY . .
RUN CINEVOL_CUDA=OFF scripts/build.sh cinevol-server cinevol cinevol-reader cinevol-viewer
RUN docker/collect-runtime.sh /opt/cinevol build/cinevol-server build/cinevol build/cinevol-reader

FROM scratch AS prebuilt
COPY runtime/ /opt/cinevol/

FROM ${PROGRAMS_FROM} AS programs

FROM ${RUNTIME_BASE}
COPY --from=programs /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --user-group --no-create-home cinevol
ENV LD_LIBRARY_PATH=/opt/cinevol/lib
USER 10001
EXPOSE 50051 9464
HEALTHCHECK --interval=10s --timeout=5s --start-period=30s \
  CMD ["/opt/cinevol/bin/cinevol", "health", "--server", "127.0.0.1:50051", "--connect-timeout", "3"]
STOPSIGNAL SIGTERM
ENTRYPOINT ["/opt/cinevol/bin/cinevol-server"]
CMD ["--listen", "0.0.0.0:50051", "--backend", "cpu", "--auth-tokens", "/etc/cinevol/tokens", \
     "--metrics-listen", "0.0.0.0:9464", "--data-root", "/data", "--drain-seconds", "25"]
