#!/usr/bin/env python3
"""Writes the seed corpus fuzz/corpus/<target>/ (committed; rerun to regenerate).

obj_pipeline inputs are `control byte + OBJ [+ NUL + MTL]` (see fuzz/pipeline.rs): the bundled
scenes' first few KB made valid (faces kept only when their vertices are defined), the MTL
features src/scene/material.rs maps, polygons, negative and forward indices, vt/vn, groups.
ray_file inputs are ray records, valid and with each field the reader rejects.
"""
import math
import os
import struct

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "fuzz", "corpus")


def write(target, name, data):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def head_valid(path, limit=3000):
    """The first `limit` bytes' worth of lines, keeping faces whose indices are defined."""
    out, nv, size = [], 0, 0
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                nv += 1
            elif w[0] == "f":
                idx = [int(x.split("/")[0]) for x in w[1:]]
                if any(i > nv or i == 0 or -i > nv for i in idx):
                    continue
            elif w[0] in ("vt", "vn"):
                continue
            out.append(line)
            size += len(line)
            if size > limit:
                break
    return "".join(out)


def obj_case(name, control, obj, mtl=None):
    data = bytes([control]) + obj.encode()
    if mtl is not None:
        data += b"\0" + mtl.encode()
    write("obj_pipeline", name, data)


def main():
    scenes = os.path.join(ROOT, "scenes")
    for i, s in enumerate(["cornell", "bunny", "dragon", "buddha", "bsdfs"]):
        obj = head_valid(os.path.join(scenes, s + ".obj"))
        mtl = open(os.path.join(scenes, s + ".mtl")).read()
        obj_case(f"scene_{s}", [3, 0x14, 0x27, 0x4f, 0x10][i], obj, mtl)

    tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
    quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    obj_case("triangle", 0, tri + "f 1 2 3\n")
    obj_case("quad", 1, quad + "f 1 2 3 4\n")
    obj_case("polygon", 2, "".join(f"v {math.cos(a / 3):.4f} {math.sin(a / 3):.4f} 0\n" for a in range(18))
             + "f " + " ".join(str(i + 1) for i in range(18)) + "\n")
    obj_case("negative_indices", 3, quad + "f -4 -3 -2\nf -4 -2 -1\n")
    obj_case("forward_indices", 4, "f 1 2 3\n" + tri)
    obj_case("vt_vn", 5, tri + "vt 0 0\nvt 1 0\nvn 0 0 1\nf 1/1/1 2/2/1 3/1/1\nf 1//1 2//1 3//1\nf 1/1 2/2 3/2\n")
    obj_case("groups_objects", 6, quad + "o a\nf 1 2 3\ng b\nf 1 3 4\ns 1\nl 1 2\np 1\n")
    obj_case("vertex_w_and_colour", 7, "v 0 0 0 1\nv 2 0 0 2\nv 0 1 0 0.5 0.2 0.3\nf 1 2 3\n")
    obj_case("degenerate", 8, "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 4\nf 1 2 4\n")
    obj_case("extreme_coords", 0x19, "v 3e38 -3e38 0\nv -3e38 3e38 1e38\nv 1e-38 1e-45 -3.4e38\n"
             "v 1e-38 0 0\nv 0 1e-38 0\nv 0 0 1e-38\nf 1 2 3\nf 4 5 6\nf 1 5 6\n")
    obj_case("bad_index", 0, tri + "f 1 2 4000000000\n")
    obj_case("bad_negative", 0, tri + "f 1 -2 -1000000000000\n")
    obj_case("nan", 0, "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    obj_case("crlf_comments", 9, "# c\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n")
    obj_case("copies", 0x2f, tri + "f 1 2 3\n" * 40)
    obj_case("grid", 0x33, "".join(f"v {x} {y} {(x * y) % 3}\n" for y in range(5) for x in range(5))
             + "".join(f"f {y*5+x+1} {y*5+x+2} {y*5+x+7} {y*5+x+6}\n" for y in range(4) for x in range(4)))

    use = "mtllib m.mtl\n" + quad + "usemtl a\nf 1 2 3\nusemtl b\nf 1 3 4\nusemtl none\nf 2 3 4\nusemtl c\nf 1 2 4\n"
    mtls = {
        "mtl_illum": "newmtl a\nKd 0.5 0.5 0.5\nillum 2\nKs 0.5 0.5 0.5\nNs 100\n"
                     "newmtl b\nillum 7\nNi 1.33\nTf 0.9 1 0.9\nnewmtl c\nillum 3\nKs 1 1 1\n",
        "mtl_bsdfs": "newmtl a\ntrilab_bsdf oren-nayar sigma=0.3\nnewmtl b\ntrilab_bsdf ashikhmin-shirley nu=100 nv=5\n"
                     "newmtl c\ntrilab_bsdf glass ior=1.7 bogus=1 x\n",
        "mtl_warnings": "newmtl a\nKa 1 1 1\nd 0.5\nTr 0.3\nmap_Kd tex.png\nbump b.png\nillum 10\nfoo bar\n"
                        "newmtl b\nKe 10 10 10\nKd 0 0 0\nnewmtl c\ntrilab_bsdf\nTf 0.5\n",
        "mtl_extreme": "newmtl a\nKd 1e38 -1 nan\nNs 1e38\nNi -1e38\nnewmtl b\nillum 99999999999\n"
                       "newmtl c\ntrilab_bsdf phong exponent=1e300\n",
        "mtl_short_colour": "newmtl a\nKd 1 2\n",
        # The spec's forms (docs/obj-mtl.md): one-number and xyz colours, spectral, -halo, maps
        # with options and spaces, PBR keys.
        "mtl_spec_forms": "newmtl a\nKd 0.5\nKs xyz 0.2 0.3 0.1\nKa spectral x.rfl\nd -halo 0.5\n"
                          "map_Kd -o 1 1 1 -bm 2 my tex.png\nmap_Ks\nrefl -type sphere s.png\nPr 0.2\n"
                          "newmtl b\nKe xyz 0 1 0\nTf 0.5 # grey\nillum 7\nnewmtl c\nKd spectral x.rfl 2\n",
    }
    for i, (name, mtl) in enumerate(mtls.items()):
        obj_case(name, i, use, mtl)
    obj_case("mtl_missing", 0, use)
    # Statements trilab ignores with a warning, a polyline tobj alone made a face of, vertex
    # colours on some vertices only, and an `mtllib` line of several names.
    obj_case("obj_ignored_statements", 0x21,
             "mtllib x.mtl my\\ m.mtl\nv 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nl 1 2 3 4\np 1 2\nf 1 2\n"
             "cstype bspline\ncurv 0 1 1 2\ncall x.obj\ncsh ls\nvw 0 0 1\nt crease 1 2\nusemtl a\nf 1 2 3\n",
             "newmtl a\nKd 0.2\n")

    ray = lambda o, tmin, d, tmax: struct.pack("<8f", *o, tmin, *d, tmax)
    good = ray((0, 0, 0), 0, (0, 0, 1), math.inf)
    write("ray_file", "valid_one", good)
    write("ray_file", "valid_many", good + ray((1, 2, 3), 0.5, (-1, 0.25, 1e-30), 10) + ray((1e38, 0, 0), 0, (1, 1, 1), 1e38))
    write("ray_file", "odd_length", good + b"\0")
    write("ray_file", "hit_records", struct.pack("<fIff", 1.5, 7, 0.25, 0.5) + struct.pack("<fIff", math.inf, 0xFFFFFFFF, 0, 0))
    names = ["origin_x", "origin_y", "origin_z", "tmin", "dir_x", "dir_y", "dir_z", "tmax"]
    for i, n in enumerate(names):
        for label, v in [("nan", math.nan), ("inf", math.inf), ("neginf", -math.inf)]:
            if n == "tmax" and label == "inf":
                continue
            vals = list(struct.unpack("<8f", good))
            vals[i] = v
            write("ray_file", f"{n}_{label}", good + struct.pack("<8f", *vals))
    write("ray_file", "zero_direction", ray((0, 0, 0), 0, (0, 0, 0), 1))


if __name__ == "__main__":
    main()
