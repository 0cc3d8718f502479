//! Fuzz target `delta`: see [`relief_proto_fuzz::delta`] for what it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relief_proto_fuzz::delta::check(data);
});
