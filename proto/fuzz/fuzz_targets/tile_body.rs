//! Fuzz target `tile_body`: see [`relief_proto_fuzz::tile_body`] for what it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relief_proto_fuzz::tile_body::check(data);
});
