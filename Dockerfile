# manyhands planning server: multi-stage build, slim non-root runtime with a health check.
#   docker build -t manyhands .
#   docker run -p 8080:8080 -e MANYHANDS_TOKEN=change-me-long-random-token -v manyhands-data:/var/lib/manyhands manyhands
# (binding 0.0.0.0 in the container requires a token of at least 16 characters; clients send
# `Authorization: Bearer change-me-long-random-token`). Check a configuration without starting:
#   docker run --rm -e MANYHANDS_TOKEN=… manyhands serve --check

FROM rust:1-slim-bookworm AS build
# clang/libclang: for crates with bindgen build scripts (bundled C libraries).
# nodejs/npm: build.rs bundles the 3-D viewer (/viewer) with npm (Node.js 18 in bookworm);
# MANYHANDS_REQUIRE_VIEWER=1 makes a failed viewer build fail the image build.
RUN apt-get update \
 && apt-get install -y --no-install-recommends clang libclang-dev pkg-config nodejs npm \
 && rm -rf /var/lib/apt/lists/*
ENV MANYHANDS_REQUIRE_VIEWER=1
WORKDIR /src
COPY . .
RUN cargo build --release --locked --bin manyhands \
 && strip target/release/manyhands

FROM debian:bookworm-slim AS runtime
RUN apt-get update \
 && apt-get install -y --no-install-recommends ca-certificates curl \
 && rm -rf /var/lib/apt/lists/* \
 && groupadd --system --gid 10001 manyhands \
 && useradd --system --uid 10001 --gid manyhands --home-dir /var/lib/manyhands --create-home manyhands
COPY --from=build /src/target/release/manyhands /usr/local/bin/manyhands
COPY --from=build /src/robots /opt/manyhands/robots
COPY --from=build /src/scenes /opt/manyhands/scenes
ENV MANYHANDS_ROBOTS=/opt/manyhands/robots \
    MANYHANDS_SCENES=/opt/manyhands/scenes \
    MANYHANDS_DATA_DIR=/var/lib/manyhands \
    MANYHANDS_BIND=0.0.0.0:8080 \
    MANYHANDS_LOG_FORMAT=json
USER manyhands:manyhands
WORKDIR /var/lib/manyhands
VOLUME ["/var/lib/manyhands"]
EXPOSE 8080
STOPSIGNAL SIGTERM
HEALTHCHECK --interval=15s --timeout=3s --start-period=20s --retries=3 \
  CMD curl -fsS http://127.0.0.1:8080/healthz > /dev/null || exit 1
ENTRYPOINT ["manyhands"]
CMD ["serve"]
