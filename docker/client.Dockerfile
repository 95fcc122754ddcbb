# The client and tools image: `cinevol` (demo, play, snapshot, loadtest,
# volumes, status, health, render, info) and `cinevol-viewer`, with
# cinevol-server for `cinevol demo`'s local server. Built with the README's own
# scripts; the final stage holds only the programs and the libraries they load.
# This workplace has no Docker engine, so no image was built here.
#
#   docker build -f docker/client.Dockerfile -t cinevol-client .
#   docker run --rm -v "$PWD/out:/out" cinevol-client demo --out /out
#   docker run --rm --network host cinevol-client status --server 127.0.0.1:50051 --token "$TOKEN"
#   docker run --rm -e DISPLAY -v /tmp/.X11-unix:/tmp/.X11-unix --entrypoint /opt/cinevol/bin/cinevol-viewer \
#     cinevol-client --server HOST:50051 --token "$TOKEN"

FROM debian:bookworm AS build
WORKDIR /src
COPY scripts/install-deps.sh scripts/
RUN scripts/install-deps.sh
COPY . .
RUN CINEVOL_CUDA=OFF scripts/build.sh \
 && docker/collect-runtime.sh /opt/cinevol build/cinevol build/cinevol-viewer build/cinevol-server build/cinevol-reader

FROM debian:bookworm-slim
COPY --from=build /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --create-home cinevol
ENV LD_LIBRARY_PATH=/opt/cinevol/lib PATH=/opt/cinevol/bin:$PATH
USER 10001
WORKDIR /home/cinevol
ENTRYPOINT ["/opt/cinevol/bin/cinevol"]
CMD ["--help"]
