# The GPU server image: cinevol-server with the CUDA renderer, and the
# `cinevol` CLI (its health check). Two ways to fill /opt/cinevol:
#   PROGRAMS_FROM=build     (default) a Debian stage installs Debian's
#                           nvidia-cuda-toolkit (non-free) and builds them with the
#                           README's scripts;
#   PROGRAMS_FROM=prebuilt  the context's runtime/ folder holds them already
#                           (scripts/images.sh --fast: the build tree's programs and the
#                           CUDA runtime they were linked with, collected by
#                           docker/collect-runtime.sh).
# The final stage holds only the programs and the libraries they load (libcuda
# stays out: the NVIDIA container toolkit mounts the host driver's), runs as uid
# 10001 and needs no writable root. docs/deploy.md.
#
#   docker build -f docker/server-gpu.Dockerfile -t cinevol-server:gpu .
#   docker run --gpus all -p 127.0.0.1:50051:50051 --read-only --tmpfs /tmp -v "$PWD/secrets:/etc/cinevol:ro" \
#     -v /data/ct:/data:ro cinevol-server:gpu

ARG BASE=debian:bookworm
ARG RUNTIME_BASE=debian:bookworm-slim
ARG PROGRAMS_FROM=build

FROM ${BASE} AS build
RUN sed -i 's/^Components: main$/Components: main contrib non-free non-free-firmware/' /etc/apt/sources.list.d/debian.sources \
 && apt-get update -q \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends nvidia-cuda-toolkit \
 && rm -rf /var/lib/apt/lists/*
WORKDIR /src
COPY scripts/install-deps.sh scripts/
COPY web/package.json web/package-lock.json web/
# npm ci of web/ behind a TLS-inspecting proxy: its CA, mounted for the build only (scripts/images.sh).
ARG NODE_EXTRA_CA_CERTS
RUN scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
COPY . .
RUN CINEVOL_CUDA=ON scripts/build.sh cinevol-server cinevol cinevol-reader \
 && docker/collect-runtime.sh /opt/cinevol build/cinevol-server build/cinevol build/cinevol-reader

FROM scratch AS prebuilt
COPY runtime/ /opt/cinevol/

FROM ${PROGRAMS_FROM} AS programs

FROM ${RUNTIME_BASE}
COPY --from=programs /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --user-group --no-create-home cinevol
ENV LD_LIBRARY_PATH=/opt/cinevol/lib \
    NVIDIA_VISIBLE_DEVICES=all \
    NVIDIA_DRIVER_CAPABILITIES=compute,utility
USER 10001
# gRPC on 50051, Prometheus metrics on 9464.
EXPOSE 50051 9464
HEALTHCHECK --interval=10s --timeout=5s --start-period=30s \
  CMD ["/opt/cinevol/bin/cinevol", "health", "--server", "127.0.0.1:50051", "--connect-timeout", "3"]
STOPSIGNAL SIGTERM
ENTRYPOINT ["/opt/cinevol/bin/cinevol-server"]
# Beyond loopback the server needs tokens (or mutual TLS): mount them at /etc/cinevol.
CMD ["--listen", "0.0.0.0:50051", "--backend", "cuda", "--auth-tokens", "/etc/cinevol/tokens", \
     "--metrics-listen", "0.0.0.0:9464", "--data-root", "/data", "--drain-seconds", "25"]
