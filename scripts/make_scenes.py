#!/usr/bin/env python3
"""Writes the synthetic test scenes in scenes/ (committed; rerun to regenerate them exactly).

- cornell.obj/.mtl: a Cornell-style box (our own geometry, 0..1 units), a square ceiling light
  facing down, two blocks. Render it with `--env 0`: the light is the only source.
- bsdfs.obj/.mtl: the same room with one sphere per BSDF, left to right: lambert, oren-nayar,
  phong, blinn-phong, ashikhmin-shirley, glass, mirror (selected with `trilab_bsdf`).

Faces wind counter-clockwise seen from the side they face (emission is one-sided).
"""
import math
import os

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes")


class Obj:
    def __init__(self):
        self.v = []
        self.lines = []

    def vert(self, p):
        self.v.append(p)
        return len(self.v)

    def use(self, mtl):
        self.lines.append(f"usemtl {mtl}")

    def quad(self, a, b, c, d):
        i = [self.vert(p) for p in (a, b, c, d)]
        self.lines.append("f {} {} {} {}".format(*i))

    def tri(self, a, b, c):
        i = [self.vert(p) for p in (a, b, c)]
        self.lines.append("f {} {} {}".format(*i))

    def box(self, lo, hi):
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        p = lambda x, y, z: (x, y, z)
        # Outward-facing, counter-clockwise seen from outside.
        self.quad(p(x0, y1, z0), p(x0, y1, z1), p(x1, y1, z1), p(x1, y1, z0))  # top
        self.quad(p(x0, y0, z1), p(x1, y0, z1), p(x1, y0, z0), p(x0, y0, z0))  # bottom
        self.quad(p(x0, y0, z1), p(x0, y1, z1), p(x0, y1, z0), p(x0, y0, z0))  # -x
        self.quad(p(x1, y0, z0), p(x1, y1, z0), p(x1, y1, z1), p(x1, y0, z1))  # +x
        self.quad(p(x0, y0, z0), p(x0, y1, z0), p(x1, y1, z0), p(x1, y0, z0))  # -z
        self.quad(p(x1, y0, z1), p(x1, y1, z1), p(x0, y1, z1), p(x0, y0, z1))  # +z

    def sphere(self, c, r, levels):
        t = (1 + 5 ** 0.5) / 2
        vs = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
              (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
        fs = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
              (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
              (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
        norm = lambda p: tuple(x / math.sqrt(sum(y * y for y in p)) for x in p)
        vs = [norm(p) for p in vs]
        for _ in range(levels):
            cache, nf = {}, []

            def mid(a, b):
                k = (min(a, b), max(a, b))
                if k not in cache:
                    vs.append(norm(tuple((vs[a][i] + vs[b][i]) / 2 for i in range(3))))
                    cache[k] = len(vs) - 1
                return cache[k]

            for a, b, c2 in fs:
                ab, bc, ca = mid(a, b), mid(b, c2), mid(c2, a)
                nf += [(a, ab, ca), (b, bc, ab), (c2, ca, bc), (ab, bc, ca)]
            fs = nf
        base = len(self.v)
        for p in vs:
            self.v.append(tuple(c[i] + r * p[i] for i in range(3)))
        for a, b, c2 in fs:
            self.lines.append(f"f {base + a + 1} {base + b + 1} {base + c2 + 1}")

    def room(self):
        # Floor, ceiling, back, left (red), right (green); open towards +z (the camera).
        self.use("white")
        self.quad((0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0))  # floor, up
        self.quad((0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1))  # ceiling, down
        self.quad((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0))  # back, +z
        self.use("red")
        self.quad((0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1))  # left, +x
        self.use("green")
        self.quad((1, 0, 0), (1, 0, 1), (1, 1, 1), (1, 1, 0))  # right, -x
        self.use("light")
        e = 0.999
        self.quad((0.38, e, 0.38), (0.62, e, 0.38), (0.62, e, 0.62), (0.38, e, 0.62))  # facing down

    def write(self, name, mtl, header):
        with open(os.path.join(HERE, name + ".obj"), "w") as f:
            f.write(header)
            f.write(f"mtllib {name}.mtl\n")
            for p in self.v:
                f.write("v {:.6f} {:.6f} {:.6f}\n".format(*p))
            f.write("\n".join(self.lines) + "\n")
        with open(os.path.join(HERE, name + ".mtl"), "w") as f:
            f.write(mtl)


ROOM_MTL = """newmtl white
Kd 0.73 0.73 0.73
illum 1
newmtl red
Kd 0.65 0.05 0.05
illum 1
newmtl green
Kd 0.12 0.45 0.15
illum 1
newmtl light
Kd 0.78 0.78 0.78
Ke 17 12 4
illum 1
"""

cornell = Obj()
cornell.room()
cornell.use("white")
cornell.box((0.18, 0.0, 0.45), (0.45, 0.6, 0.72))
cornell.box((0.55, 0.0, 0.2), (0.82, 0.3, 0.47))
cornell.write("cornell", ROOM_MTL, "# Cornell-style box for trilab (scripts/make_scenes.py). Render with --env 0.\n")

SPHERES = [
    ("s_lambert", "Kd 0.8 0.8 0.8\ntrilab_bsdf lambert"),
    ("s_oren_nayar", "Kd 0.8 0.6 0.4\ntrilab_bsdf oren-nayar sigma=0.5"),
    ("s_phong", "Kd 0.3 0.3 0.45\nKs 0.5 0.5 0.5\nNs 60\ntrilab_bsdf phong"),
    ("s_blinn_phong", "Kd 0.6 0.2 0.2\nKs 0.3 0.3 0.3\nNs 200\ntrilab_bsdf blinn-phong"),
    ("s_ashikhmin_shirley", "Kd 0.2 0.4 0.2\nKs 0.4 0.4 0.4\ntrilab_bsdf ashikhmin-shirley nu=400 nv=10"),
    ("s_glass", "Ni 1.5\nillum 7"),
    ("s_mirror", "Ks 0.95 0.95 0.95\nillum 3"),
]
bsdfs = Obj()
bsdfs.room()
mtl = ROOM_MTL
for i, (name, body) in enumerate(SPHERES):
    bsdfs.use(name)
    x = 0.1 + i * (0.8 / 6)
    z = 0.35 if i % 2 == 0 else 0.6
    bsdfs.sphere((x, 0.065, z), 0.06, 3)
    mtl += f"newmtl {name}\n{body}\n"
bsdfs.write("bsdfs", mtl, "# One sphere per BSDF in a Cornell-style box (scripts/make_scenes.py). Render with --env 0.\n")
