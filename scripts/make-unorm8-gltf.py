#!/usr/bin/env python3
"""Writes tests/data/RiggedSimple-unorm8.gltf: RiggedSimple.gltf with its WEIGHTS_0
stored as normalized unsigned bytes (unorm8), as engines export 8-bit weights.

Each vertex's float weights are rounded to multiples of 1/255 and the rounding
difference is given to (or taken from) its largest weight, so every vertex's
bytes sum to exactly 255: the weights sum to 1 on the unorm8 grid, and
skintune's unorm8 format holds them exactly (zero quantisation error). The
rest of the file (joints, positions, normals, skin, animation) is unchanged.

Usage: scripts/make-unorm8-gltf.py [tests/data]
"""
import base64
import json
import struct
import sys
from pathlib import Path

data = Path(sys.argv[1] if len(sys.argv) > 1 else "tests/data")
gltf = json.loads((data / "RiggedSimple.gltf").read_text())
prefix = "data:application/octet-stream;base64,"
buffer = gltf["buffers"][0]
assert buffer["uri"].startswith(prefix)
blob = bytearray(base64.b64decode(buffer["uri"][len(prefix):]))

primitive = gltf["meshes"][0]["primitives"][0]
accessor = gltf["accessors"][primitive["attributes"]["WEIGHTS_0"]]
assert accessor["componentType"] == 5126 and accessor["type"] == "VEC4"
view = gltf["bufferViews"][accessor["bufferView"]]
start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
stride = view.get("byteStride", 16)

packed = bytearray()
for v in range(accessor["count"]):
    weights = struct.unpack_from("<4f", blob, start + v * stride)
    total = sum(weights)
    q = [round(w / total * 255) for w in weights]
    q[max(range(4), key=lambda i: weights[i])] += 255 - sum(q)
    assert sum(q) == 255 and min(q) >= 0
    packed += bytes(q)

while len(blob) % 4:
    blob.append(0)
gltf["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(packed)})
blob += packed
buffer["byteLength"] = len(blob)
buffer["uri"] = prefix + base64.b64encode(bytes(blob)).decode()
accessor.update({"bufferView": len(gltf["bufferViews"]) - 1, "byteOffset": 0, "componentType": 5121,
                 "normalized": True})
accessor.pop("min", None)
accessor.pop("max", None)
(data / "RiggedSimple-unorm8.gltf").write_text(json.dumps(gltf, indent=1) + "\n")
