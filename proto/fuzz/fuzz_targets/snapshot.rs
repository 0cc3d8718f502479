//! Fuzz target `snapshot`: see [`relief_proto_fuzz::snapshot`] for what it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relief_proto_fuzz::snapshot::check(data);
});
