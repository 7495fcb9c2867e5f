//! Bytes -> the ray-file and hit-file readers.
#![no_main]

#[path = "../pipeline.rs"]
mod pipeline;

libfuzzer_sys::fuzz_target!(|data: &[u8]| pipeline::ray_file(data));
