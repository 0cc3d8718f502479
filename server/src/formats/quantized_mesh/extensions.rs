//! Which extensions a client asked for (its `Accept` header), and the JSON of the `metadata`
//! extension's tile availability.
//!
//! Cesium asks with `Accept: application/vnd.quantized-mesh;extensions=octvertexnormals-metadata,
//! application/octet-stream;q=0.9,*/*;q=0.01`: extension names joined by `-` in the
//! `extensions` parameter of the quantized-mesh media range. Relief writes `octvertexnormals`
//! (id 1) and `metadata` (id 4). The deprecated name `vertexnormals` does not count: clients that
//! use it (a layer.json naming only `vertexnormals`) read the extension's length as big-endian,
//! and Relief writes it little-endian as the spec now says. `watermask` (id 2) is not written.

use crate::geo::tiling::TileRange;
use serde::Serialize;

/// The quantized-mesh media type.
pub const MEDIA_TYPE: &str = "application/vnd.quantized-mesh";

/// The extensions Relief writes that a client asked for.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RequestedExtensions {
    /// `octvertexnormals`: per-vertex oct-encoded normals (extension 1).
    pub normals: bool,
    /// `metadata`: the tile's JSON metadata (extension 4).
    pub metadata: bool,
}

/// Splits `s` at `sep` outside double quotes.
fn split_unquoted(s: &str, sep: char) -> impl Iterator<Item = &str> {
    let mut parts = Vec::new();
    let mut start = 0;
    let mut quoted = false;
    for (i, c) in s.char_indices() {
        if c == '"' {
            quoted = !quoted;
        } else if c == sep && !quoted {
            parts.push(&s[start..i]);
            start = i + c.len_utf8();
        }
    }
    parts.push(&s[start..]);
    parts.into_iter()
}

/// The extensions asked for by an HTTP `Accept` header: the union of the `extensions`
/// parameters of every `application/vnd.quantized-mesh` media range (type and parameter names
/// case-insensitive, values possibly quoted), leaving out ranges with `q=0`. Anything
/// unparsable asks for nothing.
pub fn extensions_from_accept(accept: &str) -> RequestedExtensions {
    let mut out = RequestedExtensions::default();
    for range in split_unquoted(accept, ',') {
        let mut params = split_unquoted(range, ';');
        let media = params.next().unwrap_or("").trim();
        if !media.eq_ignore_ascii_case(MEDIA_TYPE) {
            continue;
        }
        let mut asked = RequestedExtensions::default();
        let mut refused = false;
        for param in params {
            let Some((name, value)) = param.split_once('=') else {
                continue;
            };
            let name = name.trim();
            let value = value.trim().trim_matches('"');
            if name.eq_ignore_ascii_case("q") {
                refused = value.parse::<f64>().is_ok_and(|q| q <= 0.0);
            } else if name.eq_ignore_ascii_case("extensions") {
                for ext in value.split('-').map(str::trim) {
                    if ext.eq_ignore_ascii_case("octvertexnormals") {
                        asked.normals = true;
                    } else if ext.eq_ignore_ascii_case("metadata") {
                        asked.metadata = true;
                    }
                }
            }
        }
        if !refused {
            out.normals |= asked.normals;
            out.metadata |= asked.metadata;
        }
    }
    out
}

#[derive(Serialize)]
struct Availability<'a> {
    available: &'a [Vec<TileRange>],
}

/// The `metadata` extension's JSON for child availability:
/// `{"available":[[{"startX":..,"startY":..,"endX":..,"endY":..}],...]}`, where `levels[i]`
/// lists the available tiles `i + 1` levels below the tile.
pub fn availability_metadata(levels: &[Vec<TileRange>]) -> String {
    // Serialising plain integers into a String cannot fail; the fallback is never taken.
    serde_json::to_string(&Availability { available: levels })
        .unwrap_or_else(|_| String::from("{}"))
}
