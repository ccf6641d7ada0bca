#!/usr/bin/env python3
"""Writes tests/data/RiggedSimple-morph.gltf: RiggedSimple.gltf with what engines'
characters carry beyond a plain skin, for the tests of morph targets, tangents and
non-uniform scale (tests/tools/skin_check_cli_test.cpp, SkinMorphCli):

- TANGENT (VEC4 float): a unit tangent perpendicular to each normal, handedness +1;
- two morph targets: target 0 dense, POSITION offset (0, 0, 0.3) on every vertex and a
  zero NORMAL offset; target 1 sparse, POSITION offset (0.1, 0, 0) on vertices 0-19 only
  (a sparse accessor), and a dense NORMAL offset (0, 0.2, 0);
- default weights (0.2, 0) on the mesh, and a LINEAR `weights` channel on the skinned node
  with keys at 0, 1 and 2 s: (0.2, 0), (0.6, 1), (0, 0.5);
- Bone.001's scale keys made non-uniform: x grows by up to 40% and z shrinks by up to 30%
  over the clip.

The offsets are simple on purpose: the tests compute the morphed mesh from them
independently of skintune's importer. Everything else (positions, normals, joints,
weights, skin, the other channels) is unchanged.

Usage: scripts/make-morph-gltf.py [tests/data]
"""
import base64
import json
import math
import struct
import sys
from pathlib import Path

data = Path(sys.argv[1] if len(sys.argv) > 1 else "tests/data")
gltf = json.loads((data / "RiggedSimple.gltf").read_text())
prefix = "data:application/octet-stream;base64,"
buffer = gltf["buffers"][0]
assert buffer["uri"].startswith(prefix)
blob = bytearray(base64.b64decode(buffer["uri"][len(prefix):]))


def read(accessor_index):
    a = gltf["accessors"][accessor_index]
    assert a["componentType"] == 5126
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[a["type"]]
    view = gltf["bufferViews"][a["bufferView"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    stride = view.get("byteStride", 4 * width)
    return [list(struct.unpack_from("<%df" % width, blob, start + i * stride)) for i in range(a["count"])]


def append(values, fmt):
    """Appends packed values as a new buffer view; returns its index."""
    while len(blob) % 4:
        blob.append(0)
    offset = len(blob)
    blob.extend(struct.pack("<" + fmt * len(values), *[x for v in values for x in (v if isinstance(v, (list, tuple)) else [v])]))
    gltf["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": len(blob) - offset})
    return len(gltf["bufferViews"]) - 1


def accessor(values, kind, extra=None):
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[kind]
    view = append(values, "f" * width if width > 1 else "f")
    entry = {"bufferView": view, "componentType": 5126, "count": len(values), "type": kind}
    if kind != "SCALAR" and values:
        entry["min"] = [min(v[i] for v in values) for i in range(width)]
        entry["max"] = [max(v[i] for v in values) for i in range(width)]
    if kind == "SCALAR":
        entry["min"], entry["max"] = [min(values)], [max(values)]
    entry.update(extra or {})
    gltf["accessors"].append(entry)
    return len(gltf["accessors"]) - 1


primitive = gltf["meshes"][0]["primitives"][0]
normals = read(primitive["attributes"]["NORMAL"])
n = len(normals)
tangents = []
for nx, ny, nz in normals:
    # Perpendicular to the normal: the normal crossed with the axis it is least along.
    axis = min(range(3), key=lambda i: abs((nx, ny, nz)[i]))
    e = [0.0, 0.0, 0.0]
    e[axis] = 1.0
    t = (ny * e[2] - nz * e[1], nz * e[0] - nx * e[2], nx * e[1] - ny * e[0])
    length = math.sqrt(sum(c * c for c in t))
    tangents.append([t[0] / length, t[1] / length, t[2] / length, 1.0])
primitive["attributes"]["TANGENT"] = accessor(tangents, "VEC4")

dense = accessor([[0.0, 0.0, 0.3]] * n, "VEC3")
zero_normals = accessor([[0.0, 0.0, 0.0]] * n, "VEC3")
sparse_count = 20
indices_view = append(list(range(sparse_count)), "H")
values_view = append([[0.1, 0.0, 0.0]] * sparse_count, "fff")
gltf["accessors"].append({"componentType": 5126, "count": n, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [0.1, 0.0, 0.0],
                          "sparse": {"count": sparse_count, "indices": {"bufferView": indices_view, "componentType": 5123},
                                     "values": {"bufferView": values_view}}})
sparse = len(gltf["accessors"]) - 1
turned_normals = accessor([[0.0, 0.2, 0.0]] * n, "VEC3")
primitive["targets"] = [{"POSITION": dense, "NORMAL": zero_normals}, {"POSITION": sparse, "NORMAL": turned_normals}]
gltf["meshes"][0]["weights"] = [0.2, 0.0]

animation = gltf["animations"][0]
times = accessor([0.0, 1.0, 2.0], "SCALAR")
weights = accessor([0.2, 0.0, 0.6, 1.0, 0.0, 0.5], "SCALAR")
animation["samplers"].append({"input": times, "output": weights, "interpolation": "LINEAR"})
animation["channels"].append({"sampler": len(animation["samplers"]) - 1, "target": {"node": 2, "path": "weights"}})

scale_channel = next(c for c in animation["channels"] if c["target"]["path"] == "scale")
scale_output = animation["samplers"][scale_channel["sampler"]]["output"]
scales = read(scale_output)
keys = len(scales)
for k, s in enumerate(scales):
    u = k / max(keys - 1, 1)
    s[0] *= 1.0 + 0.4 * u
    s[2] *= 1.0 - 0.3 * u
gltf["accessors"][scale_output] = dict(gltf["accessors"][scale_output], bufferView=append(scales, "fff"), byteOffset=0,
                                       min=[min(s[i] for s in scales) for i in range(3)],
                                       max=[max(s[i] for s in scales) for i in range(3)])

buffer["uri"] = prefix + base64.b64encode(bytes(blob)).decode()
buffer["byteLength"] = len(blob)
(data / "RiggedSimple-morph.gltf").write_text(json.dumps(gltf, indent=1) + "\n")
print("wrote", data / "RiggedSimple-morph.gltf")
