# The GPU server image: cinevol-server with the CUDA renderer, and the
# `cinevol` CLI (its health check). Built with the README's own scripts on
# Debian, CUDA from Debian's nvidia-cuda-toolkit (non-free); the final stage
# holds only the programs and the libraries they load, and runs as a user
# without privileges. The NVIDIA container toolkit gives it the GPU and the
# host's driver. docs/deploy.md says how to build and run it; this workplace
# has no Docker engine, so no image was built here.
#
#   docker build -f docker/server-gpu.Dockerfile -t cinevol-server:gpu .
#   docker run --gpus all -p 50051:50051 -v "$PWD/secrets:/etc/cinevol:ro" -v /data/ct:/data:ro cinevol-server:gpu

FROM debian:bookworm AS build
RUN sed -i 's/^Components: main$/Components: main contrib non-free non-free-firmware/' /etc/apt/sources.list.d/debian.sources \
 && apt-get update -q \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends nvidia-cuda-toolkit \
 && rm -rf /var/lib/apt/lists/*
WORKDIR /src
COPY scripts/install-deps.sh scripts/
RUN scripts/install-deps.sh
COPY . .
RUN CINEVOL_CUDA=ON scripts/build.sh \
 && docker/collect-runtime.sh /opt/cinevol build/cinevol-server build/cinevol build/cinevol-reader

FROM debian:bookworm-slim
COPY --from=build /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --no-create-home cinevol
ENV LD_LIBRARY_PATH=/opt/cinevol/lib \
    NVIDIA_VISIBLE_DEVICES=all \
    NVIDIA_DRIVER_CAPABILITIES=compute,utility
USER 10001
# gRPC on 50051, Prometheus metrics on 9464.
EXPOSE 50051 9464
HEALTHCHECK --interval=10s --timeout=5s --start-period=30s \
  CMD ["/opt/cinevol/bin/cinevol", "health", "--server", "127.0.0.1:50051", "--connect-timeout", "3"]
ENTRYPOINT ["/opt/cinevol/bin/cinevol-server"]
# Beyond loopback the server needs tokens (or mutual TLS): mount them at /etc/cinevol.
CMD ["--listen", "0.0.0.0:50051", "--backend", "cuda", "--auth-tokens", "/etc/cinevol/tokens", \
     "--metrics-listen", "0.0.0.0:9464", "--data-root", "/data", "--drain-seconds", "25"]
