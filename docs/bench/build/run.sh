#!/usr/bin/env bash
# The build benchmark of docs/building.md: `relief-server bench build` on synthetic terrain with
# one thread and with every core, and on a Cloud-Optimized GeoTIFF made by GDAL from a shared DEM,
# read from disk and over HTTP from nginx (range requests). Writes one JSON line per run to
# docs/bench/build/<commit>.jsonl and prints them as a table.
#
#   bash docs/bench/build/run.sh [SIZE]     # SIZE of synthetic:SIZE, default 16385
#
# Needs the release build (cargo build --release), gdal-bin and nginx (bash tests/setup.sh
# installs both) and ../shared/dem. Runs take about a minute each at 16385 (8 GB of memory).
set -euo pipefail
cd "$(dirname "$0")/../../.."
size=${1:-16385}
bin=${CARGO_TARGET_DIR:-target}/release/relief-server
[[ -x $bin ]] || { echo "build first: cargo build --release" >&2; exit 1; }
dem=../shared/dem/fuji_srtm3/osgearth_mt_fuji_90m.tif
[[ -f $dem ]] || { echo "$dem is missing: this benchmark needs ../shared" >&2; exit 1; }
for tool in gdal_translate nginx; do
    command -v $tool >/dev/null || { echo "$tool is missing: bash tests/setup.sh installs it" >&2; exit 1; }
done
out=docs/bench/build/$(git rev-parse --short HEAD).jsonl
: >"$out"
work=$(mktemp -d)
chmod 755 "$work" # nginx's workers run as nobody
trap 'kill $(cat "$work/nginx.pid" 2>/dev/null) 2>/dev/null || true; rm -rf "$work"' EXIT

bench() { "$bin" bench build --quiet --json "$@" | tee -a "$out" >/dev/null; }
for t in 1 $(nproc); do
    bench --dem "synthetic:$size" --threads "$t"
done

# The COG: 256 x 256 tiles, deflate with the horizontal predictor (as GDAL's COG driver writes).
gdal_translate -q -of COG -co BLOCKSIZE=256 -co COMPRESS=DEFLATE -co PREDICTOR=2 "$dem" "$work/fuji.tif"
bench --dem "$work/fuji.tif"
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
mkdir -p "$work/www" && cp "$work/fuji.tif" "$work/www/" && chmod -R a+rX "$work/www"
cat >"$work/nginx.conf" <<EOF
daemon on;
pid $work/nginx.pid;
error_log $work/error.log;
events {}
http {
    access_log $work/access.log;
    client_body_temp_path $work/body;
    proxy_temp_path $work/proxy;
    fastcgi_temp_path $work/fastcgi;
    uwsgi_temp_path $work/uwsgi;
    scgi_temp_path $work/scgi;
    server { listen 127.0.0.1:$port; root $work/www; }
}
EOF
nginx -c "$work/nginx.conf"
bench --dem "http://127.0.0.1:$port/fuji.tif"
echo "requests nginx answered for the URL build: $(wc -l <"$work/access.log")"

python3 - "$out" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| input | threads | M samples | s in all | M samples/s | per thread | cores used | peak B/sample | store B/sample | source read |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    src = f"{r['source_bytes_read']:,} of {r['source_bytes']:,} B" if r['source_bytes'] else "-"
    print(f"| {r['input']} | {r['threads']} | {r['samples']/1e6:.1f} | {r['total_s']:.2f} | "
          f"{r['samples_per_s']/1e6:.2f} | {r['samples_per_s_per_thread']/1e6:.2f} | {r['cores_used']:.2f} | "
          f"{r['peak_rss_bytes_per_sample']:.1f} | {r['store_bytes_per_sample']:.2f} | {src} |")
EOF
echo "wrote $out"
