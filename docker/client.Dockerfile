# The client and tools image: `cinevol` (demo, play, snapshot, loadtest,
# volumes, pacs, status, health, render, info) and `cinevol-viewer`, with
# cinevol-server for `cinevol demo`'s local server. /opt/cinevol is built here
# with the README's scripts (PROGRAMS_FROM=build, the default) or taken from the
# context's runtime/ folder (PROGRAMS_FROM=prebuilt: scripts/images.sh --fast).
# The final stage holds only the programs and the libraries they load.
#
#   docker build -f docker/client.Dockerfile -t cinevol-client .
#   docker run --rm --read-only --tmpfs /tmp -v "$PWD/out:/out" cinevol-client demo --out /out
#   docker run --rm --network host cinevol-client status --server 127.0.0.1:50051 --token "$TOKEN"
#   docker run --rm -e DISPLAY -v /tmp/.X11-unix:/tmp/.X11-unix --entrypoint /opt/cinevol/bin/cinevol-viewer \
#     cinevol-client --server HOST:50051 --token "$TOKEN"

ARG BASE=debian:bookworm
ARG RUNTIME_BASE=debian:bookworm-slim
ARG PROGRAMS_FROM=build

# The same build stage as server-cpu.Dockerfile's, line for line: a second image costs no second compile.
FROM ${BASE} AS build
WORKDIR /src
COPY scripts/install-deps.sh scripts/
COPY web/package.json web/package-lock.json web/
# npm ci of web/ behind a TLS-inspecting proxy: its CA, mounted for the build only (scripts/images.sh).
ARG NODE_EXTRA_CA_CERTS
RUN scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
COPY . .
RUN CINEVOL_CUDA=OFF scripts/build.sh cinevol-server cinevol cinevol-reader cinevol-viewer
RUN docker/collect-runtime.sh /opt/cinevol build/cinevol build/cinevol-viewer build/cinevol-server build/cinevol-reader

FROM scratch AS prebuilt
COPY runtime/ /opt/cinevol/

FROM ${PROGRAMS_FROM} AS programs

FROM ${RUNTIME_BASE}
COPY --from=programs /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --user-group --create-home cinevol
ENV LD_LIBRARY_PATH=/opt/cinevol/lib PATH=/opt/cinevol/bin:$PATH
USER 10001
WORKDIR /home/cinevol
HEALTHCHECK NONE
ENTRYPOINT ["/opt/cinevol/bin/cinevol"]
CMD ["--help"]
