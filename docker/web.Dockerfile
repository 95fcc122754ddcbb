# cinevol-web: the browser page and its gateway (docs/web.md). Built with the
# README's own scripts (the npm packages from web/package-lock.json); the
# final stage holds Debian's node, the bundled gateway and the page's files.
# This workplace has no Docker engine, so no image was built here.
#
#   docker build -f docker/web.Dockerfile -t cinevol-web .
#   docker run --rm --network host cinevol-web --listen 127.0.0.1:8080 --server 127.0.0.1:50051

FROM debian:bookworm AS build
WORKDIR /src
COPY scripts/install-deps.sh scripts/
COPY web/package.json web/package-lock.json web/
RUN scripts/install-deps.sh
COPY . .
# The script finds the page beside it and runs /usr/bin/node, Debian's, in both stages.
RUN CINEVOL_CUDA=OFF scripts/build.sh web \
 && mkdir -p /opt/cinevol/bin/web \
 && cp -r build/web/gateway.mjs build/web/static /opt/cinevol/bin/web/ \
 && cp build/cinevol-web /opt/cinevol/bin/

FROM debian:bookworm-slim
RUN apt-get update && apt-get install -y --no-install-recommends nodejs && rm -rf /var/lib/apt/lists/*
COPY --from=build /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --create-home cinevol
USER 10001
EXPOSE 8080 8443
HEALTHCHECK CMD node -e "fetch('http://127.0.0.1:8080/healthz').then(r=>process.exit(r.ok?0:1),()=>process.exit(1))"
ENTRYPOINT ["/opt/cinevol/bin/cinevol-web"]
CMD ["--listen", "127.0.0.1:8080", "--server", "127.0.0.1:50051"]
