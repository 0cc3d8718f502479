#!/usr/bin/env bash
# Installs and builds what the test suite needs beyond the Rust toolchain (run as root, as CI
# does; the README's test command runs this, then `cargo test --release --workspace`):
# - Debian packages: Mesa's software Vulkan driver (lavapipe) for the renderer's tests, make for
#   jemalloc, Chromium for the browser tests, HAProxy for the scale-out test, musl-tools for the
#   static server, python3-venv for the deploy validators, GDAL (gdal-bin) and nginx for the
#   Cloud-Optimized GeoTIFF test (COGs made by gdal_translate, served by range requests);
#   Node.js and npm where `node` is missing (the browser tests need Node.js 20 or newer);
# - the npm packages of web/ (pinned by web/package-lock.json);
# - a check that the browser page's committed WebAssembly (web/page/pkg/) is what
#   web/build-wasm.sh builds from the sources now;
# - the deploy validators (deploy/requirements.txt) in target/deploy-venv;
# - the static (musl) server of deploy/Dockerfile, target/x86_64-unknown-linux-musl/dist/.
# Both go under CARGO_TARGET_DIR instead of target/ where that is set.
#
# Under .ci/run each part's wall time is logged (.ci/steps.sh, RELIEF_STEP_LOG).
set -euo pipefail
cd "$(dirname "$0")/.."
source .ci/steps.sh
apt() {
    apt-get update
    apt-get install -y mesa-vulkan-drivers make chromium haproxy musl-tools python3-venv \
        gdal-bin nginx
    command -v node >/dev/null || apt-get install -y nodejs npm
}
step "setup: apt" apt
step "setup: npm" npm ci --prefix web
step "setup: wasm check" bash web/build-wasm.sh --check
# A venv moved or copied with its target directory keeps the old paths in its scripts: rebuild
# one whose validator does not start.
venv() {
    local v=${CARGO_TARGET_DIR:-target}/deploy-venv
    if ! "$v/bin/kubernetes-validate" --version >/dev/null 2>&1; then
        python3 -m venv --clear "$v"
        "$v/bin/pip" install --quiet --requirement deploy/requirements.txt
    fi
}
step "setup: deploy venv" venv
musl() {
    rustup target add x86_64-unknown-linux-musl
    cargo build --locked --profile dist --target x86_64-unknown-linux-musl -p relief-server
}
step "setup: musl server" musl
