#!/usr/bin/env python3
"""Writes the files of this folder (tests/exporter_files.rs reads them; README.md says what
each one is). Hand-made in the styles real exporters write, not copied from any tool's output.
Run from anywhere: python3 tests/data/exporters/make.py"""

import os

HERE = os.path.dirname(os.path.abspath(__file__))

# The scene every loadable file describes: a unit square (a quad, two triangles) and two
# triangles to an apex, one material each, in this order.
GEOMETRY = ["v 0 0 0", "v 1 0 0", "v 1 1 0", "v 0 1 0", "v 0.5 0.5 -0.5"]
FACES = ["f 1 2 3 4", "f 1 2 5", "f 2 3 5"]
MATERIALS = [
    ["illum 3", "Ks 0.9 0.9 0.9"],  # mirror
    ["illum 7", "Ni 1.5", "Tf 0.9 1 0.9"],  # glass
    ["Kd 0.6 0.4 0.2"],  # Lambert
]


def obj(mtllib, names, header=(), group="o Box01", geometry=GEOMETRY, geometry_first=False):
    if geometry_first:
        lines = list(header) + list(geometry) + [f"mtllib {mtllib}", group]
    else:
        lines = list(header) + [f"mtllib {mtllib}", group] + list(geometry)
    for name, face in zip(names, FACES):
        lines += [f"usemtl {name}" if name is not None else "usemtl", face]
    return lines


def mtl(names, header=(), extra=None, materials=MATERIALS):
    lines = list(header)
    for i, (name, body) in enumerate(zip(names, materials)):
        lines += [f"newmtl {name}"] + body + (extra[i] if extra else [])
    return lines


def write(name, lines, encoding="utf-8", newline="\n", prefix=b""):
    data = prefix + newline.join(lines + [""]).encode(encoding)
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)


ASCII = ["Metal1", "Metal2", "Wood"]
write("reference.obj", obj("reference.mtl", ASCII, ["# What every loadable file here must load as"]))
write("reference.mtl", mtl(ASCII))

# 3ds Max in a Western-European Windows: Latin-1 (cp1252) names, groups and comments, CRLF,
# two materials whose names differ only in a byte that is not UTF-8, a texture name likewise.
LATIN = ["Métal", "Mètal", "Bois"]
write(
    "latin1.obj",
    obj(
        "latin1.mtl",
        LATIN,
        ["# 3ds Max Wavefront OBJ Exporter - Fichier créé le 12/03/2019", "# © Société Exemple"],
        group="g Boîte01",
        geometry=[v.replace(" ", "  ", 1) for v in GEOMETRY],
    ),
    encoding="latin-1",
    newline="\r\n",
)
write(
    "latin1.mtl",
    mtl(LATIN, ["# Matériaux de la scène"], extra=[[], [], ["map_Kd bois_clair_é.jpg"]]),
    encoding="latin-1",
    newline="\r\n",
)

# An ASCII OBJ whose MTL holds Latin-1 comments only.
write("latin1_mtl.obj", obj("latin1_comments.mtl", ASCII))
write("latin1_comments.mtl", mtl(ASCII, ["# Matériaux exportés", "# (c) Société"]), encoding="latin-1")

# `usemtl` with no name before the third face; its twin names a material no MTL defines.
write("usemtl_no_name.obj", obj("reference.mtl", ["Metal1", "Metal2", None]))
write("usemtl_no_name_twin.obj", obj("reference.mtl", ["Metal1", "Metal2", "NoSuchMaterial"]))

# UTF-8 with a byte-order mark (Windows Notepad's "UTF-8 with BOM"), UTF-8 names; the mark
# comes right before the first vertex and the first `newmtl`.
UTF8 = ["Métal", "Mètal", "Bois"]
write("bom_utf8.obj", obj("bom_utf8.mtl", UTF8, geometry_first=True), prefix=b"\xef\xbb\xbf")
write("bom_utf8.mtl", mtl(UTF8), prefix=b"\xef\xbb\xbf")

# UTF-16 with a byte-order mark, both byte orders (Notepad's "Unicode" is little-endian, CRLF).
for order, codec, bom in [("le", "utf-16-le", b"\xff\xfe"), ("be", "utf-16-be", b"\xfe\xff")]:
    write(f"utf16{order}.obj", obj(f"utf16{order}.mtl", UTF8, ["# UTF-16"]), codec, "\r\n", bom)
    write(f"utf16{order}.mtl", mtl(UTF8), codec, "\r\n", bom)

# Number spellings C's strtod and Rust's f32 parser both read, for the same values (no -0: its
# bits differ from 0's, and the scene hash compares bits).
write(
    "numbers.obj",
    obj(
        "numbers.mtl",
        ASCII,
        geometry=["v 0e0 .0e+0 +0", "v 1e+0 0. 0E-3", "v 1.E+0 10e-1 0.000", "v .0 +1. 0", "v 5.e-1 .5 -.5e0"],
    ),
)
write(
    "numbers.mtl",
    mtl(
        ASCII,
        materials=[["illum 3", "Ks 9e-1 .9 0.90e0"], ["illum 7", "Ni 15e-1", "Tf .9 1.e0 9.E-1"], ["Kd 6e-1 .4 2E-1"]],
    ),
)

# What must stay an error, naming the file and the line.
TRI = ["v 0 0 0", "v 1 0 0", "v 0 1 0", "f 1 2 3"]
write("refused_two_points.obj", ["v 0 0 0", "v 1.2.3 0 0", "v 0 1 0", "f 1 2 3"])
write("refused_nan.obj", ["v 0 0 0", "v 1 0 0", "v 0 nan 0", "f 1 2 3"])
write("refused_inf.obj", ["v 0 0 0", "v 1 0 inf", "v 0 1 0", "f 1 2 3"])
write("refused_latin1_number.obj", ["v 0 0 0", "v 1·5 0 0", "v 0 1 0", "f 1 2 3"], encoding="latin-1")
data = b"\xff\xfe" + "\n".join(TRI + [""]).encode("utf-16-le")
with open(os.path.join(HERE, "refused_utf16_truncated.obj"), "wb") as f:
    f.write(data[:-1])
