// Started as a copy of the project's shared peer (../shared/peers/embree_rays.cpp); benchmark-only,
// built by scripts/embree-peer.sh, never by the main build. Added here (issue 53): the packet modes
// `trace8` and `trace16` (same arguments as `trace`), which trace the file's rays with rtcIntersect8 /
// rtcIntersect16, because issue 53 sets a target against Embree's packet traversal beside its
// rtcIntersect1 one (the coherent primary rays are where packets pay). A packet is 8 or 16
// consecutive rays of the file, in the file's order (a last partial group masked off by the `valid`
// array); threads split the rays on group boundaries; hits are written in the file's order and the
// result line names the call (`embree3 packet8 threads=..`). A width the library does not run
// natively (RTC_DEVICE_PROPERTY_NATIVE_RAY8/16_SUPPORTED) is refused with a message on stderr and
// exit status 3, never silently emulated.
// Peer baseline: Embree 3 (Debian's libembree-dev) on the same ray files as the project.
// Ray file: little-endian records of 8 f32: org.xyz, tmin, dir.xyz, tmax (32 bytes).
// Hit file: records of f32 t (inf = miss), u32 prim (0xFFFFFFFF = miss), f32 u, f32 v (16 bytes).
// Triangle ids are face order in the OBJ (faces with more than 3 vertices fan-triangulated).
#include <embree3/rtcore.h>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>
#include <algorithm>
#include <limits>

struct V3 { float x, y, z; };
static V3 sub(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
static V3 add(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
static V3 mul(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
static float dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
static V3 norm(V3 a) { float l = std::sqrt(dot(a, a)); return mul(a, 1.0f / l); }

struct Ray { float ox, oy, oz, tmin, dx, dy, dz, tmax; };
struct Hit { float t; uint32_t prim; float u, v; };

struct Mesh { std::vector<V3> v; std::vector<uint32_t> idx; V3 lo, hi; };

static Mesh load_obj(const char* path) {
  Mesh m; std::ifstream f(path); if (!f) { fprintf(stderr, "cannot open %s\n", path); exit(2); }
  std::string line;
  while (std::getline(f, line)) {
    if (line.size() < 2) continue;
    if (line[0] == 'v' && line[1] == ' ') { std::istringstream s(line.substr(2)); V3 p; s >> p.x >> p.y >> p.z; m.v.push_back(p); }
    else if (line[0] == 'f' && line[1] == ' ') {
      std::istringstream s(line.substr(2)); std::string tok; std::vector<long> ids;
      while (s >> tok) { long i = std::stol(tok.substr(0, tok.find('/'))); if (i < 0) i = (long)m.v.size() + i + 1; ids.push_back(i - 1); }
      for (size_t k = 1; k + 1 < ids.size(); k++) { m.idx.push_back(ids[0]); m.idx.push_back(ids[k]); m.idx.push_back(ids[k + 1]); }
    }
  }
  m.lo = {1e30f, 1e30f, 1e30f}; m.hi = {-1e30f, -1e30f, -1e30f};
  for (auto& p : m.v) { m.lo = {std::min(m.lo.x, p.x), std::min(m.lo.y, p.y), std::min(m.lo.z, p.z)}; m.hi = {std::max(m.hi.x, p.x), std::max(m.hi.y, p.y), std::max(m.hi.z, p.z)}; }
  return m;
}

struct Scene { RTCDevice dev; RTCScene scn; double build_ms; };
static Scene build(const Mesh& m, bool robust, RTCDevice dev = nullptr) {
  Scene s; s.dev = dev ? dev : rtcNewDevice(nullptr);
  auto t0 = std::chrono::steady_clock::now();
  s.scn = rtcNewScene(s.dev);
  rtcSetSceneBuildQuality(s.scn, RTC_BUILD_QUALITY_HIGH);
  if (robust) rtcSetSceneFlags(s.scn, RTC_SCENE_FLAG_ROBUST);
  RTCGeometry g = rtcNewGeometry(s.dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  float* vb = (float*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.v.size());
  memcpy(vb, m.v.data(), m.v.size() * sizeof(V3));
  unsigned* ib = (unsigned*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m.idx.size() / 3);
  memcpy(ib, m.idx.data(), m.idx.size() * sizeof(uint32_t));
  rtcCommitGeometry(g); rtcAttachGeometry(s.scn, g); rtcReleaseGeometry(g);
  rtcCommitScene(s.scn);
  s.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return s;
}

// rtcIntersect1 on rays [b, e), one call per ray.
static void trace_range(RTCScene scn, const Ray* r, Hit* h, size_t b, size_t e) {
  RTCIntersectContext ctx; rtcInitIntersectContext(&ctx);
  for (size_t i = b; i < e; i++) {
    RTCRayHit rh; rh.ray.org_x = r[i].ox; rh.ray.org_y = r[i].oy; rh.ray.org_z = r[i].oz; rh.ray.tnear = r[i].tmin;
    rh.ray.dir_x = r[i].dx; rh.ray.dir_y = r[i].dy; rh.ray.dir_z = r[i].dz; rh.ray.tfar = r[i].tmax;
    rh.ray.mask = ~0u; rh.ray.flags = 0; rh.ray.time = 0; rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scn, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) h[i] = {INFINITY, 0xFFFFFFFFu, 0, 0};
    else h[i] = {rh.ray.tfar, rh.hit.primID, rh.hit.u, rh.hit.v};
  }
}

// The packet calls, by packet type (the valid mask and the packet aligned to the packet's width).
static void intersect(const int* valid, RTCScene scn, RTCIntersectContext* ctx, RTCRayHit8* rh) { rtcIntersect8(valid, scn, ctx, rh); }
static void intersect(const int* valid, RTCScene scn, RTCIntersectContext* ctx, RTCRayHit16* rh) { rtcIntersect16(valid, scn, ctx, rh); }

// rtcIntersect8/16 on rays [b, e), b on a group boundary: groups of W consecutive rays of the file,
// the last one masked where e - b is not a multiple of W. Inactive lanes get an empty ray
// (tnear 0 > tfar -inf) besides their valid flag 0, so nothing in them is left uninitialised.
template <int W, typename RayHitW>
static void trace_packets(RTCScene scn, const Ray* r, Hit* h, size_t b, size_t e) {
  RTCIntersectContext ctx; rtcInitIntersectContext(&ctx);
  alignas(W * 4) int valid[W];
  alignas(W * 4) RayHitW rh;
  for (size_t g = b; g < e; g += W) {
    for (int j = 0; j < W; j++) {
      size_t i = g + j; bool on = i < e;
      valid[j] = on ? -1 : 0;
      rh.ray.org_x[j] = on ? r[i].ox : 0; rh.ray.org_y[j] = on ? r[i].oy : 0; rh.ray.org_z[j] = on ? r[i].oz : 0;
      rh.ray.tnear[j] = on ? r[i].tmin : 0;
      rh.ray.dir_x[j] = on ? r[i].dx : 0; rh.ray.dir_y[j] = on ? r[i].dy : 0; rh.ray.dir_z[j] = on ? r[i].dz : 1;
      rh.ray.tfar[j] = on ? r[i].tmax : -INFINITY;
      rh.ray.time[j] = 0; rh.ray.mask[j] = ~0u; rh.ray.id[j] = j; rh.ray.flags[j] = 0;
      rh.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID; rh.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
    }
    intersect(valid, scn, &ctx, &rh);
    for (int j = 0; j < W && g + j < e; j++) {
      if (rh.hit.geomID[j] == RTC_INVALID_GEOMETRY_ID) h[g + j] = {INFINITY, 0xFFFFFFFFu, 0, 0};
      else h[g + j] = {rh.ray.tfar[j], rh.hit.primID[j], rh.hit.u[j], rh.hit.v[j]};
    }
  }
}

static_assert(alignof(RTCRayHit8) == 32 && alignof(RTCRayHit16) == 64, "Embree's packets are aligned to their width");

// Which Embree call traces: rtcIntersect1 (`trace`), rtcIntersect8 (`trace8`), rtcIntersect16 (`trace16`).
enum class Api { Ray1 = 1, Packet8 = 8, Packet16 = 16 };

// Traces every ray with `api` on `threads` threads, each taking a contiguous range of whole groups
// of `api`'s width (the last thread's range ends with the file); returns the wall time, s.
static double trace_all(RTCScene scn, const std::vector<Ray>& rays, std::vector<Hit>& hits, int threads, Api api = Api::Ray1) {
  hits.resize(rays.size());
  auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> ts; size_t n = rays.size(), w = (size_t)api, groups = (n + w - 1) / w;
  for (int k = 0; k < threads; k++) {
    size_t b = std::min(n, groups * k / threads * w), e = std::min(n, groups * (k + 1) / threads * w);
    switch (api) {
      case Api::Ray1: ts.emplace_back(trace_range, scn, rays.data(), hits.data(), b, e); break;
      case Api::Packet8: ts.emplace_back(trace_packets<8, RTCRayHit8>, scn, rays.data(), hits.data(), b, e); break;
      case Api::Packet16: ts.emplace_back(trace_packets<16, RTCRayHit16>, scn, rays.data(), hits.data(), b, e); break;
    }
  }
  for (auto& t : ts) t.join();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

static void write_file(const char* p, const void* d, size_t n) { FILE* f = fopen(p, "wb"); fwrite(d, 1, n, f); fclose(f); }
static std::vector<Ray> read_rays(const char* p) {
  FILE* f = fopen(p, "rb"); if (!f) { fprintf(stderr, "cannot open %s\n", p); exit(2); }
  fseek(f, 0, SEEK_END); long n = ftell(f); fseek(f, 0, SEEK_SET);
  std::vector<Ray> r(n / sizeof(Ray)); size_t got = fread(r.data(), sizeof(Ray), r.size(), f); fclose(f); r.resize(got); return r;
}

// Camera: looks at the bounding-box centre from direction (0.3, 0.25, 1), 45 degree vertical fov, framing the bounding sphere.
static std::vector<Ray> primary(const Mesh& m, int w, int h) {
  V3 c = mul(add(m.lo, m.hi), 0.5f); float rad = 0.5f * std::sqrt(dot(sub(m.hi, m.lo), sub(m.hi, m.lo)));
  float fov = 45.0f * 3.14159265f / 180.0f; V3 fwd = mul(norm(V3{0.3f, 0.25f, 1.0f}), -1.0f);
  V3 eye = sub(c, mul(fwd, rad / std::tan(fov / 2) * 0.9f));
  V3 right = norm(cross(fwd, V3{0, 1, 0})); V3 up = cross(right, fwd);
  float th = std::tan(fov / 2), aspect = (float)w / h; std::vector<Ray> rays;
  for (int y = 0; y < h; y++) for (int x = 0; x < w; x++) {
    float px = (2 * (x + 0.5f) / w - 1) * th * aspect, py = (1 - 2 * (y + 0.5f) / h) * th;
    V3 d = norm(add(fwd, add(mul(right, px), mul(up, py))));
    rays.push_back({eye.x, eye.y, eye.z, 0.0f, d.x, d.y, d.z, INFINITY});
  }
  return rays;
}

int main(int argc, char** argv) {
  if (argc < 3) { fprintf(stderr, "usage: embree_rays gen-primary OBJ W H OUT | gen-diffuse OBJ W H SEED PER_HIT OUT | gen-random OBJ N SEED OUT | trace|trace8|trace16 OBJ RAYS OUT [repeat] [robust]\n"); return 2; }
  std::string mode = argv[1]; Mesh m = load_obj(argv[2]);
  int threads = std::max(1u, std::thread::hardware_concurrency());
  if (mode == "gen-primary") { auto r = primary(m, atoi(argv[3]), atoi(argv[4])); write_file(argv[5], r.data(), r.size() * sizeof(Ray)); return 0; }
  if (mode == "gen-diffuse") {
    auto r = primary(m, atoi(argv[3]), atoi(argv[4])); Scene s = build(m, false); std::vector<Hit> h; trace_all(s.scn, r, h, threads);
    std::mt19937 rng(atoi(argv[5])); std::uniform_real_distribution<float> U(0, 1); std::vector<Ray> out;
    float scale = std::max({std::fabs(m.lo.x), std::fabs(m.lo.y), std::fabs(m.lo.z), std::fabs(m.hi.x), std::fabs(m.hi.y), std::fabs(m.hi.z)});
    int per_hit = atoi(argv[6]);
    for (size_t i = 0; i < r.size(); i++) for (int k = 0; k < per_hit; k++) {
      if (h[i].prim == 0xFFFFFFFFu) continue;
      const uint32_t* t = &m.idx[3 * h[i].prim]; V3 a = m.v[t[0]], b = m.v[t[1]], c = m.v[t[2]];
      V3 n = norm(cross(sub(b, a), sub(c, a))); V3 d{r[i].dx, r[i].dy, r[i].dz}; if (dot(n, d) > 0) n = mul(n, -1);
      V3 p = add(add(a, mul(sub(b, a), h[i].u)), mul(sub(c, a), h[i].v));
      p = add(p, mul(n, 1e-4f * scale));
      float u1 = U(rng), u2 = U(rng), r1 = std::sqrt(u1), phi = 2 * 3.14159265f * u2;
      V3 tx = norm(std::fabs(n.x) > 0.5f ? cross(n, V3{0, 1, 0}) : cross(n, V3{1, 0, 0})); V3 ty = cross(n, tx);
      V3 dd = norm(add(add(mul(tx, r1 * std::cos(phi)), mul(ty, r1 * std::sin(phi))), mul(n, std::sqrt(std::max(0.0f, 1 - u1)))));
      out.push_back({p.x, p.y, p.z, 0.0f, dd.x, dd.y, dd.z, INFINITY});
    }
    write_file(argv[7], out.data(), out.size() * sizeof(Ray)); return 0;
  }
  if (mode == "gen-random") {
    // Rays from random points on the bounding sphere (x1.5) towards random points inside the bounding box.
    V3 c = mul(add(m.lo, m.hi), 0.5f); float rad = 0.5f * std::sqrt(dot(sub(m.hi, m.lo), sub(m.hi, m.lo)));
    std::mt19937 rng(atoi(argv[4])); std::uniform_real_distribution<float> U(0, 1); std::vector<Ray> out; long n = atol(argv[3]);
    for (long i = 0; i < n; i++) {
      float z = 2 * U(rng) - 1, phi = 2 * 3.14159265f * U(rng), s = std::sqrt(1 - z * z);
      V3 o = add(c, mul(V3{s * std::cos(phi), s * std::sin(phi), z}, 1.5f * rad));
      V3 tgt{m.lo.x + U(rng) * (m.hi.x - m.lo.x), m.lo.y + U(rng) * (m.hi.y - m.lo.y), m.lo.z + U(rng) * (m.hi.z - m.lo.z)};
      V3 d = norm(sub(tgt, o)); out.push_back({o.x, o.y, o.z, 0.0f, d.x, d.y, d.z, INFINITY});
    }
    write_file(argv[5], out.data(), out.size() * sizeof(Ray)); return 0;
  }
  if (mode == "trace" || mode == "trace8" || mode == "trace16") {
    if (argc < 5) { fprintf(stderr, "usage: embree_rays %s OBJ RAYS OUT [repeat] [robust]\n", mode.c_str()); return 2; }
    Api api = mode == "trace8" ? Api::Packet8 : mode == "trace16" ? Api::Packet16 : Api::Ray1;
    RTCDevice dev = rtcNewDevice(nullptr);
    if (!dev) { fprintf(stderr, "embree_rays: rtcNewDevice failed (error %d)\n", (int)rtcGetDeviceError(nullptr)); return 2; }
    if (api != Api::Ray1) {
      bool w8 = api == Api::Packet8;
      RTCDeviceProperty prop = w8 ? RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED : RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED;
      if (!rtcGetDeviceProperty(dev, prop)) {
        fprintf(stderr, "embree_rays: %s (%s, %d-wide packets) is not supported by this Embree library on this CPU: %s is 0\n",
                mode.c_str(), w8 ? "rtcIntersect8" : "rtcIntersect16", (int)api,
                w8 ? "RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED" : "RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED");
        return 3;
      }
    }
    auto rays = read_rays(argv[3]); int repeat = argc > 5 ? atoi(argv[5]) : 5; bool robust = argc > 6 && std::string(argv[6]) == "robust";
    Scene s = build(m, robust, dev); std::vector<Hit> h; double best = 1e30;
    for (int k = 0; k < repeat; k++) best = std::min(best, trace_all(s.scn, rays, h, threads, api));
    write_file(argv[4], h.data(), h.size() * sizeof(Hit));
    size_t hitn = 0; for (auto& x : h) hitn += x.prim != 0xFFFFFFFFu;
    // rtcIntersect1 keeps the shared peer's line (`embree3 default ...`); a packet mode names its call.
    const char* call = api == Api::Packet8 ? "packet8 " : api == Api::Packet16 ? "packet16 " : "";
    const char* kind = robust ? "robust" : api == Api::Ray1 ? "default" : "";
    printf("embree3 %s%s%sthreads=%d tris=%zu rays=%zu hits=%zu build_ms=%.1f best_s=%.4f mrays_per_s=%.2f\n",
           call, kind, *kind ? " " : "", threads, m.idx.size() / 3, rays.size(), hitn, s.build_ms, best, rays.size() / best / 1e6);
    return 0;
  }
  fprintf(stderr, "unknown mode %s\n", mode.c_str()); return 2;
}
