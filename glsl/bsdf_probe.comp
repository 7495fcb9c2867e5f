#version 460
// trilab:intersector none
// trilab:variants main lambert=BSDF_MASK:1
// BSDF probe: runs the dispatcher (bsdf.glsl) on one (material, wo, v)
// per invocation so that the host can test it (tests/bsdf_probe.rs, src/render/bsdf.rs).
//   mode 0, sample: v = u; writes the sample (wi, pdf, weight, flags) and, at the sampled wi,
//                   f = bsdf_eval and eval_pdf = bsdf_pdf (consistency checks).
//   mode 1, eval:   v = wi; writes wi = v, f = bsdf_eval, pdf = eval_pdf = bsdf_pdf.
// Variants: `main` compiles every kind in; `lambert` only Lambert (BSDF_MASK = 1), to test that
// excluded kinds evaluate to 0 and never sample.
// Rust twins: trilab::render::bsdf::{ProbeIn, ProbeOut, ProbePush}.
#extension GL_GOOGLE_include_directive : require

#include "shared.glsl"
#include "bsdf.glsl"

struct ProbeIn {
    vec3 wo;
    uint material;  // index into the materials texel buffer
    vec3 v;         // sample: the three uniforms; eval: wi
    uint pad;
};

struct ProbeOut {
    vec3 wi;
    float pdf;
    vec3 weight;
    uint flags;  // bit 0: bsdf_sample returned true; bit 1: s.delta; bit 2: bsdf_is_delta(kind)
    vec3 f;
    float eval_pdf;
};

layout(std430, set = 0, binding = BINDING_BSDF_PROBE_IN) readonly buffer ProbeInputs { ProbeIn probe_in[]; };
layout(std430, set = 0, binding = BINDING_BSDF_PROBE_OUT) writeonly buffer ProbeOutputs { ProbeOut probe_out[]; };

layout(push_constant) uniform Push {
    uint mode;
    uint count;
} pc;

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    ProbeIn p = probe_in[i];
    Material m = load_material(p.material);
    ProbeOut o;
    uint delta_kind = bsdf_is_delta(m.kind) ? 4u : 0u;
    if (pc.mode == 0u) {
        BsdfSample s;
        bool ok = bsdf_sample(m, p.wo, p.v, s);
        o.wi = s.wi;
        o.pdf = s.pdf;
        o.weight = s.weight;
        o.flags = (ok ? 1u : 0u) | (s.delta ? 2u : 0u) | delta_kind;
        o.f = bsdf_eval(m, p.wo, s.wi);
        o.eval_pdf = bsdf_pdf(m, p.wo, s.wi);
    } else {
        o.wi = p.v;
        o.f = bsdf_eval(m, p.wo, p.v);
        o.pdf = bsdf_pdf(m, p.wo, p.v);
        o.eval_pdf = o.pdf;
        o.weight = vec3(0.0);
        o.flags = delta_kind;
    }
    probe_out[i] = o;
}
