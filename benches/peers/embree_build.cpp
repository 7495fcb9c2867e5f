// Benchmark-only peer for `trilab build-bench --embree`: times Embree 3's BVH builder
// (rtcBuildBVH, Debian's libembree-dev) on the triangles trilab builds over, and writes the
// tree it built in trilab's node layout so trilab validates it and prices it with its own SAH
// formula. Built by scripts/embree-peer.sh into target/peers/, never by the main build.
//
// Usage: embree_build INPUT TREE_OUT --threads N --repeat K --leaf L --min-leaf M
//                     --block B --max-depth D [--commit]
//
// INPUT (little-endian, written by trilab's build_bench module):
//   8 bytes "TLBUILD1", u64 vertices V, u64 triangles T, u64 primitives P,
//   f32 positions[3V], u32 indices[3T],
//   P build primitives of 32 bytes, RTCBuildPrimitive's layout: f32 lower[3], u32 geomID (0),
//   f32 upper[3], u32 primID (the triangle id). trilab leaves degenerate triangles out of P.
// TREE_OUT: 8 bytes "TLBVHOUT", u64 nodes N, u64 slots S, N nodes of 32 bytes
//   (f32 min[3], u32 left_or_first, f32 max[3], u32 count: count 0 = inner node with children
//   at left_or_first and left_or_first + 1; else a leaf of `count` slots from left_or_first),
//   then u32 triangle id per slot. Root at 0, depth first, left child first.
// stdout: one JSON object: threads, build_ms (one per timed run), commit_ms (with --commit).
//
// Timed: rtcBuildBVH alone (its callbacks included), on a fresh copy of the primitives
// (rtcBuildBVH reorders them) and a fresh RTCBVH each run; one untimed warm-up run first.
// RTC_BUILD_QUALITY_HIGH without a splitPrimitive callback is Embree's binned SAH builder
// (spatial splits need the callback and spare array capacity; they would reference a triangle
// from several leaves). --commit also times rtcCommitScene on a triangle-mesh scene with
// RTC_BUILD_QUALITY_HIGH (Embree's own BVH4/8 with spatial splits: a reference time, not a tree
// trilab can price).
#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

struct Node {
  bool leaf;
};
struct Inner : Node {
  RTCBounds bounds[2];
  Node* child[2];
};
struct Leaf : Node {
  unsigned count;
  unsigned ids[1];  // `count` of them (allocated to size)
};

[[noreturn]] void fail(const std::string& m) {
  fprintf(stderr, "embree_build: %s\n", m.c_str());
  exit(2);
}

void on_error(void*, RTCError code, const char* str) {
  fprintf(stderr, "embree_build: Embree error %d: %s\n", (int)code, str ? str : "");
  exit(3);
}

void* create_node(RTCThreadLocalAllocator alloc, unsigned int child_count, void*) {
  if (child_count != 2) fail("Embree asked for a node of " + std::to_string(child_count) + " children");
  void* p = rtcThreadLocalAlloc(alloc, sizeof(Inner), 16);
  Inner* n = new (p) Inner;
  n->leaf = false;
  n->child[0] = n->child[1] = nullptr;
  return n;
}

void set_children(void* node, void** children, unsigned int count, void*) {
  for (unsigned i = 0; i < count; i++) static_cast<Inner*>(node)->child[i] = static_cast<Node*>(children[i]);
}

void set_bounds(void* node, const RTCBounds** bounds, unsigned int count, void*) {
  for (unsigned i = 0; i < count; i++) static_cast<Inner*>(node)->bounds[i] = *bounds[i];
}

void* create_leaf(RTCThreadLocalAllocator alloc, const RTCBuildPrimitive* prims, size_t n, void*) {
  void* p = rtcThreadLocalAlloc(alloc, sizeof(Leaf) + (n ? n - 1 : 0) * sizeof(unsigned), 16);
  Leaf* l = new (p) Leaf;
  l->leaf = true;
  l->count = (unsigned)n;
  for (size_t i = 0; i < n; i++) l->ids[i] = prims[i].primID;
  return l;
}

struct OutNode {
  float min[3];
  uint32_t left_or_first;
  float max[3];
  uint32_t count;
};
static_assert(sizeof(OutNode) == 32, "trilab's 32-byte node");
static_assert(sizeof(RTCBuildPrimitive) == 32, "input record size");

void set_box(OutNode& o, const RTCBounds& b) {
  o.min[0] = b.lower_x; o.min[1] = b.lower_y; o.min[2] = b.lower_z;
  o.max[0] = b.upper_x; o.max[1] = b.upper_y; o.max[2] = b.upper_z;
}

// Embree's tree in trilab's layout: children of a node adjacent, depth first, left first.
void flatten(const Node* root, const RTCBounds& root_box, std::vector<OutNode>& nodes, std::vector<uint32_t>& slots) {
  nodes.assign(1, OutNode{});
  set_box(nodes[0], root_box);
  std::vector<std::pair<const Node*, size_t>> stack{{root, 0}};
  while (!stack.empty()) {
    auto [n, i] = stack.back();
    stack.pop_back();
    if (n->leaf) {
      const Leaf* l = static_cast<const Leaf*>(n);
      nodes[i].left_or_first = (uint32_t)slots.size();
      nodes[i].count = l->count;
      slots.insert(slots.end(), l->ids, l->ids + l->count);
      continue;
    }
    const Inner* in = static_cast<const Inner*>(n);
    size_t c = nodes.size();
    nodes.resize(c + 2);
    nodes[i].left_or_first = (uint32_t)c;
    nodes[i].count = 0;
    for (int k = 0; k < 2; k++) {
      if (!in->child[k]) fail("inner node without a child");
      set_box(nodes[c + k], in->bounds[k]);
    }
    stack.push_back({in->child[1], c + 1});
    stack.push_back({in->child[0], c});
  }
}

template <class T>
void read_into(FILE* f, T* dst, size_t n, const char* what) {
  if (n && fread(dst, sizeof(T), n, f) != n) fail(std::string("input truncated in ") + what);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    fprintf(stderr,
            "usage: embree_build INPUT TREE_OUT --threads N --repeat K --leaf L --min-leaf M --block B --max-depth D "
            "[--commit]\n");
    return 2;
  }
  unsigned threads = 0, repeat = 5, leaf = 4, min_leaf = 1, block = 1, max_depth = 64;
  bool commit = false;
  for (int i = 3; i < argc; i++) {
    std::string a = argv[i];
    auto val = [&]() -> unsigned {
      if (i + 1 >= argc) fail(a + " needs a value");
      return (unsigned)strtoul(argv[++i], nullptr, 10);
    };
    if (a == "--threads") threads = val();
    else if (a == "--repeat") repeat = val();
    else if (a == "--leaf") leaf = val();
    else if (a == "--min-leaf") min_leaf = val();
    else if (a == "--block") block = val();
    else if (a == "--max-depth") max_depth = val();
    else if (a == "--commit") commit = true;
    else fail("unknown option " + a);
  }
  if (repeat == 0 || leaf == 0 || leaf > RTC_BUILD_MAX_PRIMITIVES_PER_LEAF || min_leaf == 0 || min_leaf > leaf)
    fail("bad --repeat/--leaf/--min-leaf");

  FILE* f = fopen(argv[1], "rb");
  if (!f) fail(std::string("cannot open ") + argv[1]);
  char magic[8];
  uint64_t nv = 0, nt = 0, np = 0;
  read_into(f, magic, 8, "header");
  if (memcmp(magic, "TLBUILD1", 8) != 0) fail("input is not a TLBUILD1 file");
  read_into(f, &nv, 1, "header");
  read_into(f, &nt, 1, "header");
  read_into(f, &np, 1, "header");
  if (nv > (1ull << 32) || nt > (1ull << 32) || np > nt) fail("implausible counts in header");
  std::vector<float> pos(3 * nv);
  std::vector<uint32_t> idx(3 * nt);
  std::vector<RTCBuildPrimitive> prims(np);
  read_into(f, pos.data(), pos.size(), "positions");
  read_into(f, idx.data(), idx.size(), "indices");
  read_into(f, prims.data(), prims.size(), "primitives");
  fclose(f);
  for (uint32_t i : idx)
    if (i >= nv) fail("vertex index out of range");

  std::string cfg = threads ? "threads=" + std::to_string(threads) : std::string();
  RTCDevice dev = rtcNewDevice(cfg.c_str());
  if (!dev) fail("rtcNewDevice failed");
  rtcSetDeviceErrorFunction(dev, on_error, nullptr);

  std::vector<double> build_ms;
  std::vector<OutNode> nodes;
  std::vector<uint32_t> slots;
  std::vector<RTCBuildPrimitive> work(np);
  for (unsigned run = 0; run <= repeat; run++) {
    std::copy(prims.begin(), prims.end(), work.begin());
    RTCBVH bvh = rtcNewBVH(dev);
    RTCBuildArguments args = rtcDefaultBuildArguments();
    args.buildQuality = RTC_BUILD_QUALITY_HIGH;
    args.maxBranchingFactor = 2;
    args.maxDepth = max_depth;
    args.sahBlockSize = block;
    args.minLeafSize = min_leaf;
    args.maxLeafSize = leaf;
    args.traversalCost = 1.0f;
    args.intersectionCost = 1.0f;
    args.bvh = bvh;
    args.primitives = work.data();
    args.primitiveCount = np;
    args.primitiveArrayCapacity = np;
    args.createNode = create_node;
    args.setNodeChildren = set_children;
    args.setNodeBounds = set_bounds;
    args.createLeaf = create_leaf;
    args.splitPrimitive = nullptr;
    auto t0 = std::chrono::steady_clock::now();
    Node* root = static_cast<Node*>(rtcBuildBVH(&args));
    auto t1 = std::chrono::steady_clock::now();
    if (!root) fail("rtcBuildBVH returned no root");
    if (run > 0) build_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    if (run == repeat) {
      // Root box: its children's, or (a leaf root) its primitives'.
      RTCBounds box{};
      if (root->leaf) {
        box = {INFINITY, INFINITY, INFINITY, 0.0f, -INFINITY, -INFINITY, -INFINITY, 0.0f};
        for (const auto& p : prims) {
          box.lower_x = std::min(box.lower_x, p.lower_x); box.upper_x = std::max(box.upper_x, p.upper_x);
          box.lower_y = std::min(box.lower_y, p.lower_y); box.upper_y = std::max(box.upper_y, p.upper_y);
          box.lower_z = std::min(box.lower_z, p.lower_z); box.upper_z = std::max(box.upper_z, p.upper_z);
        }
      } else {
        const Inner* in = static_cast<const Inner*>(root);
        const RTCBounds &a = in->bounds[0], &b = in->bounds[1];
        box = {std::min(a.lower_x, b.lower_x), std::min(a.lower_y, b.lower_y), std::min(a.lower_z, b.lower_z), 0.0f,
               std::max(a.upper_x, b.upper_x), std::max(a.upper_y, b.upper_y), std::max(a.upper_z, b.upper_z), 0.0f};
      }
      flatten(root, box, nodes, slots);
    }
    rtcReleaseBVH(bvh);
  }

  std::vector<double> commit_ms;
  if (commit) {
    // Embree may read 16 bytes at the last vertex of a shared buffer: pad it.
    std::vector<float> padded(pos);
    padded.resize(pos.size() + 4, 0.0f);
    for (unsigned run = 0; run <= repeat; run++) {
      RTCScene scn = rtcNewScene(dev);
      rtcSetSceneBuildQuality(scn, RTC_BUILD_QUALITY_HIGH);
      RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, padded.data(), 0, 3 * sizeof(float), nv);
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, idx.data(), 0, 3 * sizeof(uint32_t), nt);
      rtcCommitGeometry(g);
      rtcAttachGeometry(scn, g);
      rtcReleaseGeometry(g);
      auto t0 = std::chrono::steady_clock::now();
      rtcCommitScene(scn);
      auto t1 = std::chrono::steady_clock::now();
      if (run > 0) commit_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      rtcReleaseScene(scn);
    }
  }
  rtcReleaseDevice(dev);

  FILE* o = fopen(argv[2], "wb");
  if (!o) fail(std::string("cannot create ") + argv[2]);
  uint64_t nn = nodes.size(), ns = slots.size();
  bool ok = fwrite("TLBVHOUT", 1, 8, o) == 8 && fwrite(&nn, 8, 1, o) == 1 && fwrite(&ns, 8, 1, o) == 1 &&
            fwrite(nodes.data(), sizeof(OutNode), nn, o) == nn && fwrite(slots.data(), 4, ns, o) == ns;
  if (fclose(o) != 0 || !ok) fail(std::string("cannot write ") + argv[2]);

  auto list = [](const std::vector<double>& v) {
    std::string s = "[";
    for (size_t i = 0; i < v.size(); i++) s += (i ? "," : "") + std::to_string(v[i]);
    return s + "]";
  };
  printf("{\"threads\":%u,\"build_ms\":%s,\"commit_ms\":%s,\"median_build_ms\":%.3f}\n", threads, list(build_ms).c_str(),
         list(commit_ms).c_str(), median(build_ms));
  return 0;
}
