#!/usr/bin/env python3
"""Writes scenes/cornell-box/ and scenes/cornell-box-glossy/ as self-contained glTF 2.0 files.

Geometry: the published Cornell box measurements (https://www.graphics.cornell.edu/online/box/data.html),
in millimetres there, in metres here. Reflectances and light radiance are the RGB values commonly used for
that data set (e.g. by Mitsuba and pbrt's scene ports). Run from anywhere: python3 scenes/make_cornell_box.py
"""
import base64, json, math, os, struct

HERE = os.path.dirname(os.path.abspath(__file__))
MM = 0.001

FLOOR = [(552.8, 0, 0), (0, 0, 0), (0, 0, 559.2), (549.6, 0, 559.2)]
CEILING = [(556, 548.8, 0), (556, 548.8, 559.2), (0, 548.8, 559.2), (0, 548.8, 0)]
BACK = [(549.6, 0, 559.2), (0, 0, 559.2), (0, 548.8, 559.2), (556, 548.8, 559.2)]
GREEN = [(0, 0, 559.2), (0, 0, 0), (0, 548.8, 0), (0, 548.8, 559.2)]  # x = 0, right as seen by the camera
RED = [(552.8, 0, 0), (549.6, 0, 559.2), (556, 548.8, 559.2), (556, 548.8, 0)]  # x ~ 550, left
# The light hangs 0.1 mm below the ceiling so the two never share a plane.
LIGHT = [(343, 548.7, 227), (343, 548.7, 332), (213, 548.7, 332), (213, 548.7, 227)]
SHORT_TOP = [(130, 165, 65), (82, 165, 225), (240, 165, 272), (290, 165, 114)]
TALL_TOP = [(423, 330, 247), (265, 330, 296), (314, 330, 456), (472, 330, 406)]
BOX_CENTER = (278, 274.4, 279.6)

WHITE = (0.725, 0.71, 0.68)
REDC = (0.63, 0.065, 0.05)
GREENC = (0.14, 0.45, 0.091)
LIGHT_RADIANCE = (17.0, 12.0, 4.0)


def sub(a, b): return tuple(x - y for x, y in zip(a, b))
def dot(a, b): return sum(x * y for x, y in zip(a, b))
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a):
    l = math.sqrt(dot(a, a))
    return tuple(x / l for x in a)
def centroid(q): return tuple(sum(p[i] for p in q) / len(q) for i in range(3))


def oriented(quad, towards):
    """Returns the quad wound so that its normal points towards the point `towards` (mm)."""
    n = cross(sub(quad[1], quad[0]), sub(quad[2], quad[0]))
    return quad if dot(n, sub(towards, centroid(quad))) > 0 else list(reversed(quad))


def block(top):
    """Top and four sides of a block standing on the floor, all facing outwards."""
    c = centroid(top)
    inside = (c[0], c[1] * 0.5, c[2])
    quads = [top]
    for i in range(4):
        a, b = top[i], top[(i + 1) % 4]
        quads.append([a, b, (b[0], 0, b[2]), (a[0], 0, a[2])])
    away = lambda q: tuple(2 * x - y for x, y in zip(centroid(q), inside))
    return [oriented(q, away(q)) for q in quads]


class Builder:
    def __init__(self):
        self.blob = bytearray()
        self.accessors, self.views, self.meshes_prims = [], [], []

    def _view(self, data, target):
        while len(self.blob) % 4:
            self.blob.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data), "target": target})
        self.blob += data
        return len(self.views) - 1

    def primitive(self, quads, material):
        pos, nrm, idx = [], [], []
        for q in quads:
            n = norm(cross(sub(q[1], q[0]), sub(q[2], q[0])))
            base = len(pos)
            for p in q:
                pos.append(tuple(x * MM for x in p))
                nrm.append(n)
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
        pv = self._view(b"".join(struct.pack("<3f", *p) for p in pos), 34962)
        nv = self._view(b"".join(struct.pack("<3f", *n) for n in nrm), 34962)
        iv = self._view(b"".join(struct.pack("<H", i) for i in idx), 34963)
        lo = [min(p[i] for p in pos) for i in range(3)]
        hi = [max(p[i] for p in pos) for i in range(3)]
        self.accessors += [
            {"bufferView": pv, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": nv, "componentType": 5126, "count": len(nrm), "type": "VEC3"},
            {"bufferView": iv, "componentType": 5123, "count": len(idx), "type": "SCALAR"},
        ]
        a = len(self.accessors)
        return {"attributes": {"POSITION": a - 3, "NORMAL": a - 2}, "indices": a - 1, "material": material}


def material(name, color, metallic=0.0, roughness=1.0, specular=0.0, emission=None):
    m = {"name": name,
         "pbrMetallicRoughness": {"baseColorFactor": list(color) + [1.0], "metallicFactor": metallic,
                                  "roughnessFactor": roughness},
         "extensions": {"KHR_materials_specular": {"specularFactor": specular}}}
    if emission:
        strength = max(emission)
        m["emissiveFactor"] = [e / strength for e in emission]
        m["extensions"]["KHR_materials_emissive_strength"] = {"emissiveStrength": strength}
    return m


def write(folder, glossy):
    b = Builder()
    walls_in = lambda qs: [oriented(q, BOX_CENTER) for q in qs]
    materials = [material("white", WHITE), material("red", REDC), material("green", GREENC),
                 material("light", (0.78, 0.78, 0.78), emission=LIGHT_RADIANCE)]
    floor_mat, tall_mat = 0, 0
    if glossy:
        materials.append(material("glossy floor", WHITE, metallic=0.0, roughness=0.2, specular=1.0))
        materials.append(material("glossy metal", (0.95, 0.93, 0.88), metallic=1.0, roughness=0.3, specular=1.0))
        floor_mat, tall_mat = 4, 5
    prims = [
        b.primitive(walls_in([CEILING, BACK]), 0),
        b.primitive(walls_in([FLOOR]), floor_mat),
        b.primitive(walls_in([RED]), 1),
        b.primitive(walls_in([GREEN]), 2),
        b.primitive([oriented(LIGHT, (278, 0, 279.6))], 3),
        b.primitive(block(SHORT_TOP), 0),
        b.primitive(block(TALL_TOP), tall_mat),
    ]
    name = os.path.basename(folder)
    doc = {
        "asset": {"version": "2.0", "generator": "nrad scenes/make_cornell_box.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"name": name, "nodes": [0, 1]}],
        "nodes": [
            {"name": "cornell box", "mesh": 0},
            # Classic camera at (278, 273, -800) mm looking down +Z: glTF cameras look down -Z, so turn 180 deg about Y.
            {"name": "camera", "camera": 0, "translation": [0.278, 0.273, -0.8], "rotation": [0.0, 1.0, 0.0, 0.0]},
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 2 * math.atan(12.5 / 35.0), "aspectRatio": 1.0,
                                                               "znear": 0.01}}],
        "meshes": [{"name": "cornell box", "primitives": prims}],
        "materials": materials,
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(b.blob)).decode()}],
    }
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name + ".gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    write(os.path.join(HERE, "cornell-box"), glossy=False)
    write(os.path.join(HERE, "cornell-box-glossy"), glossy=True)
