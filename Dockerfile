# syntax=docker/dockerfile:1
#
# Container image of the stereo distance service: a static binary on `scratch`, run as a
# non-root user, listening on 0.0.0.0:8080, with a HEALTHCHECK through the binary itself.
#
# Where the Rust image can be pulled:
#   docker build -t stereo-distance .
#
# Where no base image can be pulled (as in this project's CI): build the static binary on the
# host and hand its folder to the runtime stage in place of the `build` stage:
#   RUSTFLAGS='-C target-feature=+crt-static' \
#     cargo build --release --locked --target x86_64-unknown-linux-gnu
#   podman build --format docker \
#     --build-context build=target/x86_64-unknown-linux-gnu/release -t stereo-distance .
# (`--format docker` keeps the HEALTHCHECK, which the OCI image format has no field for.)

ARG RUST_VERSION=1.95

# ---- build: a statically linked binary, dependencies cached in their own layer ----
FROM docker.io/library/rust:${RUST_VERSION}-bookworm AS build
WORKDIR /src
ENV CARGO_BUILD_TARGET=x86_64-unknown-linux-gnu \
    RUSTFLAGS="-C target-feature=+crt-static"
# Build the dependencies alone first: this layer is reused until Cargo.toml or Cargo.lock change.
COPY Cargo.toml Cargo.lock ./
# The environment of the build (.cargo/config.toml) and the Swagger UI files it blanks.
COPY .cargo ./.cargo
COPY swagger-ui-trim ./swagger-ui-trim
# The manifest names the bench targets and the workspace's other member, so their sources
# must exist for cargo to read it.
COPY benches ./benches
COPY crates ./crates
RUN mkdir src \
 && printf 'fn main() {}\n' > src/main.rs \
 && touch src/lib.rs \
 && cargo build --release --locked \
 && rm -rf src
COPY src ./src
# The live stream's AsyncAPI document, served at /asyncapi.yaml from the binary.
COPY openapi/asyncapi.yaml ./openapi/asyncapi.yaml
RUN touch src/main.rs src/lib.rs \
 && cargo build --release --locked \
 && cp target/x86_64-unknown-linux-gnu/release/stereo-distance /stereo-distance

# ---- runtime: nothing but the binary ----
FROM scratch AS runtime
LABEL org.opencontainers.image.title="stereo-distance" \
      org.opencontainers.image.description="Stereo correspondence to distance, with its error, over HTTP/JSON" \
      org.opencontainers.image.licenses="MIT"
COPY --from=build /stereo-distance /stereo-distance
# scratch has no /etc/passwd, so the user is numeric: 65532 is distroless's "nonroot".
USER 65532:65532
ENV HOST=0.0.0.0 \
    PORT=8080 \
    LOG_FORMAT=json
EXPOSE 8080
HEALTHCHECK --interval=10s --timeout=3s --start-period=2s --retries=3 \
    CMD ["/stereo-distance", "healthcheck", "--timeout", "2s"]
ENTRYPOINT ["/stereo-distance"]
