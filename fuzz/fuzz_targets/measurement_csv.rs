#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| maglab_fuzz_targets::measurement_csv(data));
