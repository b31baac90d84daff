#!/usr/bin/env python3
"""Writes the objects of issue 42 that are placed into baked scenes (`nrad render|validate --insert
FILE@x,y,z`), each as a self-contained glTF 2.0 file in scenes/objects/:

- sphere.gltf: a sphere of radius 80 mm, white Lambertian (0.8, no specular layer), its origin at its centre.
- sphere-glossy.gltf: the same sphere as a glossy metal (base colour 0.9, roughness 0.3).
- mannequin.gltf: a 300 mm figure of ellipsoids (head, torso, arms, legs), white Lambertian (0.8), its origin
  between its feet (place it on a floor at the floor's height).

Smooth normals, triangles. Units: metres. Run from anywhere: python3 scenes/make_objects.py
"""
import base64, json, math, os, struct

HERE = os.path.dirname(os.path.abspath(__file__))


def ellipsoid(center, radii, rings=24, segments=48):
    """Vertices, normals and triangles of an ellipsoid (a UV sphere scaled by radii, moved to center)."""
    pos, nrm, tri = [], [], []
    for i in range(rings + 1):
        theta = math.pi * i / rings
        for j in range(segments + 1):
            phi = 2.0 * math.pi * j / segments
            u = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
            pos.append(tuple(c + r * x for c, r, x in zip(center, radii, u)))
            n = tuple(x / r for x, r in zip(u, radii))  # the normal of a scaled sphere: inverse-transpose
            length = math.sqrt(sum(x * x for x in n))
            nrm.append(tuple(x / length for x in n))
    for i in range(rings):
        for j in range(segments):
            a, b = i * (segments + 1) + j, (i + 1) * (segments + 1) + j
            if i > 0:
                tri.append((a, a + 1, b))  # wound counter-clockwise seen from outside
            if i < rings - 1:
                tri.append((a + 1, b + 1, b))
    return pos, nrm, tri


def write(name, parts, material):
    pos, nrm, idx = [], [], []
    for p, n, t in parts:
        base = len(pos)
        pos += p
        nrm += n
        idx += [base + k for tr in t for k in tr]
    blob = bytearray()
    views = []
    for data, target in ((b"".join(struct.pack("<3f", *p) for p in pos), 34962),
                         (b"".join(struct.pack("<3f", *n) for n in nrm), 34962),
                         (b"".join(struct.pack("<I", i) for i in idx), 34963)):
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
        blob += data
    lo = [min(p[i] for p in pos) for i in range(3)]
    hi = [max(p[i] for p in pos) for i in range(3)]
    doc = {
        "asset": {"version": "2.0", "generator": "nrad scenes/make_objects.py"},
        "extensionsUsed": ["KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"name": name, "nodes": [0]}],
        "nodes": [{"name": name, "mesh": 0}],
        "meshes": [{"name": name, "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]}],
        "materials": [material],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": len(nrm), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()}],
    }
    folder = os.path.join(HERE, "objects")
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name + ".gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


def material(name, color, metallic=0.0, roughness=1.0, specular=0.0):
    return {"name": name,
            "pbrMetallicRoughness": {"baseColorFactor": [color] * 3 + [1.0], "metallicFactor": metallic, "roughnessFactor": roughness},
            "extensions": {"KHR_materials_specular": {"specularFactor": specular}}}


R = 0.08
write("sphere", [ellipsoid((0, 0, 0), (R, R, R))], material("white", 0.8))
write("sphere-glossy", [ellipsoid((0, 0, 0), (R, R, R))], material("glossy metal", 0.9, metallic=1.0, roughness=0.3, specular=1.0))
write("mannequin", [
    ellipsoid((0, 0.268, 0), (0.03, 0.032, 0.03), 16, 32),  # head
    ellipsoid((0, 0.175, 0), (0.05, 0.07, 0.03), 16, 32),  # torso
    ellipsoid((-0.066, 0.17, 0), (0.014, 0.062, 0.014), 12, 24),  # arms
    ellipsoid((0.066, 0.17, 0), (0.014, 0.062, 0.014), 12, 24),
    ellipsoid((-0.024, 0.062, 0), (0.019, 0.062, 0.019), 12, 24),  # legs
    ellipsoid((0.024, 0.062, 0), (0.019, 0.062, 0.019), 12, 24),
], material("white", 0.8))
