# The CPU server image: cinevol-server rendering on every core (no GPU), and
# the `cinevol` CLI (its health check). Built with the README's own scripts;
# the final stage holds only the programs and the libraries they load, and
# runs as a user without privileges. docs/deploy.md says how to build and run
# it; this workplace has no Docker engine, so no image was built here.
#
#   docker build -f docker/server-cpu.Dockerfile -t cinevol-server:cpu .
#   docker run -p 50051:50051 -v "$PWD/secrets:/etc/cinevol:ro" -v /data/ct:/data:ro cinevol-server:cpu

FROM debian:bookworm AS build
WORKDIR /src
COPY scripts/install-deps.sh scripts/
RUN scripts/install-deps.sh
COPY . .
RUN CINEVOL_CUDA=OFF scripts/build.sh \
 && docker/collect-runtime.sh /opt/cinevol build/cinevol-server build/cinevol build/cinevol-reader

FROM debian:bookworm-slim
COPY --from=build /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --no-create-home cinevol
ENV LD_LIBRARY_PATH=/opt/cinevol/lib
USER 10001
EXPOSE 50051 9464
HEALTHCHECK --interval=10s --timeout=5s --start-period=30s \
  CMD ["/opt/cinevol/bin/cinevol", "health", "--server", "127.0.0.1:50051", "--connect-timeout", "3"]
ENTRYPOINT ["/opt/cinevol/bin/cinevol-server"]
CMD ["--listen", "0.0.0.0:50051", "--backend", "cpu", "--auth-tokens", "/etc/cinevol/tokens", \
     "--metrics-listen", "0.0.0.0:9464", "--data-root", "/data", "--drain-seconds", "25"]
