//! OBJ (+ MTL) bytes -> Mesh -> BVH (both leaf policies) -> validate -> every encoder.
#![no_main]

#[path = "../pipeline.rs"]
mod pipeline;

libfuzzer_sys::fuzz_target!(|data: &[u8]| pipeline::obj_pipeline(data));
