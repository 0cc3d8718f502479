//! End-to-end tests of Relief live in `tests/`; this library is empty.
