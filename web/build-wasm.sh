#!/usr/bin/env bash
# Rebuilds the browser page's WebAssembly and its JS glue, web/page/pkg/, from web/wasm/ (the
# relief-wasm crate: relief-proto compiled to wasm32-unknown-unknown). The server embeds the
# committed pkg/, so run this after changing proto/ or web/wasm/, and commit what it writes.
#
#   bash web/build-wasm.sh          rebuild web/page/pkg/
#   bash web/build-wasm.sh --check  rebuild into a temporary folder and fail if the committed
#                                   pkg/ differs (the README's test command runs this)
#
# Needs the wasm32-unknown-unknown target and wasm-bindgen-cli 0.2.130 (the version the
# wasm-bindgen crate is pinned to); it installs both when they are missing. The build is
# deterministic for a given toolchain.
set -euo pipefail
cd "$(dirname "$0")/.."
VERSION=0.2.130
if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown
fi
BINDGEN="${WASM_BINDGEN:-$(command -v wasm-bindgen || echo "$HOME/.cargo/bin/wasm-bindgen")}"
if ! "$BINDGEN" --version 2>/dev/null | grep -qx "wasm-bindgen $VERSION"; then
  # The lock file's versions first; a registry mirror without one of them gets the newest
  # compatible versions instead.
  cargo install --locked wasm-bindgen-cli --version "$VERSION" ||
    cargo install wasm-bindgen-cli --version "$VERSION"
  BINDGEN="$HOME/.cargo/bin/wasm-bindgen"
fi
TARGET="${CARGO_TARGET_DIR:-target}"
# No machine's paths in the module (panic locations of dependencies name their source files):
# the same sources give the same bytes wherever they are built with the same toolchain.
CARGO_HOME_DIR="${CARGO_HOME:-$HOME/.cargo}"
REMAP="--remap-path-prefix=$CARGO_HOME_DIR=/cargo --remap-path-prefix=$PWD=/relief"
# A target directory outside the repository (CARGO_TARGET_DIR, as CI's cache) is named as if it
# were target/, where build scripts' generated sources would be; rustc applies the last match.
TARGET_ABS="$(realpath -m "$TARGET")"
case "$TARGET_ABS" in
  "$PWD"/*) ;;
  *) REMAP="$REMAP --remap-path-prefix=$TARGET_ABS=/relief/target" ;;
esac
export CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS="$REMAP"
cargo build --profile wasm -p relief-wasm --target wasm32-unknown-unknown
TOOLCHAIN="$(rustc -V)"
OUT=web/page/pkg
if [ "${1:-}" = --check ]; then
  OUT="$(mktemp -d)"
  trap 'rm -rf "$OUT"' EXIT
fi
"$BINDGEN" --target web --no-typescript --remove-name-section --remove-producers-section \
  --out-dir "$OUT" "$TARGET/wasm32-unknown-unknown/wasm/relief_wasm.wasm"
echo "$TOOLCHAIN" >"$OUT/TOOLCHAIN"
if [ "${1:-}" = --check ]; then
  if ! diff -r -x TOOLCHAIN "$OUT" web/page/pkg >/dev/null; then
    echo "web/page/pkg/ is stale: run bash web/build-wasm.sh and commit web/page/pkg/" >&2
    if ! diff -q "$OUT/TOOLCHAIN" web/page/pkg/TOOLCHAIN >/dev/null; then
      echo "(or the toolchain differs: pkg/ was built with $(cat web/page/pkg/TOOLCHAIN 2>/dev/null), this is $TOOLCHAIN)" >&2
    fi
    exit 1
  fi
  echo "web/page/pkg/ is up to date"
else
  echo "wrote $OUT: $(wc -c <"$OUT/relief_wasm_bg.wasm") bytes of wasm, $(gzip -9c "$OUT/relief_wasm_bg.wasm" | wc -c) gzipped"
fi
