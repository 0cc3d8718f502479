//! Fuzz target `message`: see [`relief_proto_fuzz::message`] for what it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relief_proto_fuzz::message::check(data);
});
