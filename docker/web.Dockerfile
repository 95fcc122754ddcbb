# cinevol-web: the browser page and its gateway (docs/web.md). /opt/cinevol is
# built here with the README's scripts (PROGRAMS_FROM=build, the default; the
# npm packages from web/package-lock.json) or taken from the context's runtime/
# folder (PROGRAMS_FROM=prebuilt: scripts/images.sh --fast, the build tree's
# bundle). The final stage holds Debian's node, the bundled gateway and the
# page's files, runs as uid 10001 and needs no writable root.
#
#   docker build -f docker/web.Dockerfile -t cinevol-web .
#   docker run --rm --network host cinevol-web --listen 127.0.0.1:8080 --server 127.0.0.1:50051
# Beyond loopback the gateway needs TLS (--tls-cert/--tls-key); its health check then asks
# CINEVOL_WEB_HEALTH (e.g. https://127.0.0.1:8443/healthz), not the default http://127.0.0.1:8080/healthz.

ARG BASE=debian:bookworm
ARG RUNTIME_BASE=debian:bookworm-slim
ARG PROGRAMS_FROM=build

# The same first steps as the server images' build stage: their layers are shared.
FROM ${BASE} AS build
WORKDIR /src
COPY scripts/install-deps.sh scripts/
COPY web/package.json web/package-lock.json web/
# npm ci of web/ behind a TLS-inspecting proxy: its CA, mounted for the build only (scripts/images.sh).
ARG NODE_EXTRA_CA_CERTS
RUN scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
COPY . .
# The script finds the page beside it and runs /usr/bin/node, Debian's, in the final stage.
RUN CINEVOL_CUDA=OFF scripts/build.sh web \
 && mkdir -p /opt/cinevol/bin/web \
 && cp -r build/web/gateway.mjs build/web/static /opt/cinevol/bin/web/ \
 && cp build/cinevol-web /opt/cinevol/bin/

FROM scratch AS prebuilt
COPY runtime/ /opt/cinevol/

FROM ${PROGRAMS_FROM} AS programs

FROM ${RUNTIME_BASE}
RUN apt-get update -q \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends nodejs \
 && rm -rf /var/lib/apt/lists/*
COPY --from=programs /opt/cinevol /opt/cinevol
RUN useradd --system --uid 10001 --user-group --no-create-home cinevol
USER 10001
EXPOSE 8080 8443
ENV CINEVOL_WEB_HEALTH=http://127.0.0.1:8080/healthz
# A probe of its own loopback port: the certificate is the gateway's own, not checked here.
HEALTHCHECK --interval=10s --timeout=5s --start-period=10s CMD ["/usr/bin/node", "-e", \
  "const u=new URL(process.env.CINEVOL_WEB_HEALTH);require(u.protocol==='https:'?'https':'http').get(u,{rejectUnauthorized:false},r=>process.exit(r.statusCode===200?0:1)).on('error',()=>process.exit(1))"]
STOPSIGNAL SIGTERM
ENTRYPOINT ["/opt/cinevol/bin/cinevol-web"]
CMD ["--listen", "127.0.0.1:8080", "--server", "127.0.0.1:50051"]
