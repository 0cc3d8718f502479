#!/usr/bin/env bash
# Relief's adaptive tile meshes against their peers, side by side in one run:
# `rqt` against pymartini (mapbox martini's RTIN) and `tin` against pydelatin (hmm's greedy
# insertion), on crops of the real DEMs in ../shared/dem, each pair at the same maximum error
# measured by the same brute-force oracle (relief-server's `TriMesh::max_error`).
#
#   bash server/tools/peer_meshes.sh            # prints two Markdown tables
#
# Needs python3 with venv, and ../shared beside the repository (not on a user's machine). The
# peers are installed, pinned, into a virtual environment under target/ (PEER_VENV overrides).
# What the tables say: docs/rqt.md ("Against pymartini") and docs/tin.md ("Against pydelatin").
set -euo pipefail
cd "$(dirname "$0")/../.."

dems=../shared/dem
if [ ! -d "$dems" ]; then
    echo "peer_meshes: $dems is missing: the DEMs live in ../shared, beside the repository" >&2
    exit 2
fi
venv=${PEER_VENV:-target/peer-venv}
if [ ! -x "$venv/bin/python" ]; then
    echo "== installing pymartini and pydelatin into $venv"
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check \
    numpy pymartini==0.6.0 pydelatin==0.4.0
py="$venv/bin/python"

echo "== building the examples"
cargo build --release --quiet -p relief-server --example rqt_figure --example tin_cli
bin=${CARGO_TARGET_DIR:-target}/release/examples

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo
echo "## rqt against pymartini"
echo
echo "### rqt alone (every crop, brute-force error)"
"$bin/rqt_figure" table "$work"
echo
echo "### pymartini's time per crop"
"$py" server/tools/pymartini_compare.py "$work"
echo
echo "### at the same error"
"$bin/rqt_figure" compare "$work"

echo
echo "## tin against pydelatin"
echo
"$py" server/tools/pydelatin_compare.py "$bin/tin_cli" "$dems"/*/*.png
