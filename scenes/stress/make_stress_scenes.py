#!/usr/bin/env python3
"""Writes the stress scenes of scenes/stress/ (issue 5, "stiff and extreme cases") as self-contained glTF 2.0.

Each scene folder gets a README saying what it stresses and what must hold; tests/stress/ asserts it.
Run from anywhere: python3 scenes/stress/make_stress_scenes.py
"""
import base64, copy, json, math, os, struct, sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import make_cornell_box as cb  # noqa: E402  (the glTF builder and the Cornell box data)


class Mesh:
    """Triangles (each with its own vertices and flat normal) grouped by material."""

    def __init__(self):
        self.groups = {}

    def tri(self, a, b, c, mat):
        self.groups.setdefault(mat, []).append((a, b, c))

    def quad(self, q, mat):
        self.tri(q[0], q[1], q[2], mat)
        self.tri(q[0], q[2], q[3], mat)

    def gltf(self, materials, camera_translation, camera_rotation, yfov=1.0, name="stress"):
        blob = bytearray()
        accessors, views, prims = [], [], []

        def view(data, target):
            while len(blob) % 4:
                blob.append(0)
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
            blob.extend(data)
            return len(views) - 1

        for mat, tris in sorted(self.groups.items()):
            pos, nrm = [], []
            for a, b, c in tris:
                n = cb.cross(cb.sub(b, a), cb.sub(c, a))
                l = math.sqrt(cb.dot(n, n))
                n = tuple(x / l for x in n) if l > 0 else (0.0, 1.0, 0.0)
                pos += [a, b, c]
                nrm += [n, n, n]
            pv = view(b"".join(struct.pack("<3f", *p) for p in pos), 34962)
            nv = view(b"".join(struct.pack("<3f", *n) for n in nrm), 34962)
            iv = view(b"".join(struct.pack("<I", i) for i in range(len(pos))), 34963)
            lo = [min(p[i] for p in pos) for i in range(3)]
            hi = [max(p[i] for p in pos) for i in range(3)]
            accessors += [
                {"bufferView": pv, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": lo, "max": hi},
                {"bufferView": nv, "componentType": 5126, "count": len(nrm), "type": "VEC3"},
                {"bufferView": iv, "componentType": 5125, "count": len(pos), "type": "SCALAR"},
            ]
            a = len(accessors)
            prims.append({"attributes": {"POSITION": a - 3, "NORMAL": a - 2}, "indices": a - 1, "material": mat})
        return {
            "asset": {"version": "2.0", "generator": "nrad scenes/stress/make_stress_scenes.py"},
            "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
            "scene": 0,
            "scenes": [{"name": name, "nodes": [0, 1]}],
            "nodes": [{"name": name, "mesh": 0},
                      {"name": "camera", "camera": 0, "translation": list(camera_translation), "rotation": list(camera_rotation)}],
            "cameras": [{"type": "perspective", "perspective": {"yfov": yfov, "aspectRatio": 1.0, "znear": 1e-4}}],
            "meshes": [{"name": name, "primitives": prims}],
            "materials": materials,
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{"byteLength": len(blob),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()}],
        }


README = {
    "furnace": ("A closed sphere (radius 1, flat triangles, facing inwards) emitting Le = 1 with diffuse albedo {a}. "
                "Every point in every direction sees Le / (1 - a) = {L:g}; paths run about {n:g} bounces (unbounded "
                "depth, Russian roulette).",
                "The path tracer's image mean is within 1% of {L:g}. The asset's radiance at 2,000 random surface "
                "points and directions has a mean error below {mean}% and a 95th percentile below {p95}%. No NaN."),
    "tiny-emitter": ("A 4 x 3 x 4 m room lit only by a 1 mm square of radiance 1e6 (power pi W): fireflies and a huge "
                     "dynamic range in the training targets.",
                     "No NaN or Inf in training samples, weights, reference or neural image; the errors are reported."),
    "scaled": ("The Cornell box scaled by {s} (a node scale): ray offsets, voxel arithmetic and Embree precision "
               "far from metre-sized scenes.",
               "The neural image's relMSE equals the unscaled box's within 25% (radiance does not depend on scale)."),
    "degenerate": ("A lit floor with a point triangle, a collinear triangle, two 1-micrometre slivers and a 1 cm "
                   "triangle alone in a corner voxel; baked with a floor of 4 samples per voxel.",
                   "Degenerate triangles are dropped and counted at import; a voxel with fewer than 10 samples trains "
                   "without NaN; validation runs."),
    "radiance-span": ("Five emissive tiles of radiance 1e-4, 1e-2, 1, 1e2 and 1e4 on a wall, lighting a floor: eight "
                      "decades in one scene, one tile per voxel on a 5 x 1 x 1 grid.",
                      "Training converges (no constant fallback) and the error is reported per decade of reference "
                      "luminance."),
}


def save(folder, doc, stresses, must_hold):
    path = os.path.join(HERE, folder)
    os.makedirs(path, exist_ok=True)
    with open(os.path.join(path, folder + ".gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    with open(os.path.join(path, "README.md"), "w") as f:
        f.write("# %s\n\nWritten by `scenes/stress/make_stress_scenes.py`; asserted by `tests/stress/stress_test.cpp` "
                "(CTest label `stress`); figures in `docs/stability.md`.\n\n**Stresses:** %s\n\n**Must hold:** %s\n"
                % (folder, stresses, must_hold))


# Looking down -Z (glTF's default): the identity rotation. Looking down +Z: 180 degrees about Y.
IDENTITY = (0.0, 0.0, 0.0, 1.0)
LOOK_DOWN = (-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))  # -90 degrees about X: the camera looks down -Y


def furnace(albedo):
    """A closed sphere of radius 1, facing inwards, emitting Le = 1 with diffuse albedo a: L = Le / (1 - a)."""
    m = Mesh()
    rings, segments = 12, 24
    def point(i, j):
        theta, phi = math.pi * i / rings, 2 * math.pi * j / segments
        return (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1)
            # Wound so the normal points inwards (towards the centre). At the poles one of the two is a point.
            inward = lambda p, q, r: (p, q, r) if cb.dot(cb.cross(cb.sub(q, p), cb.sub(r, p)), cb.centroid([p, q, r])) < 0 else (p, r, q)
            if i < rings - 1:
                m.tri(*inward(a, b, c), 0)
            if i > 0:
                m.tri(*inward(a, c, d), 0)
    mat = cb.material("furnace", (albedo,) * 3, emission=(1.0, 1.0, 1.0))
    return m.gltf([mat], (0.0, 0.0, 0.0), IDENTITY, yfov=1.2, name="furnace")


def box_room(m, size, mat):
    """The six inward-facing walls of an axis-aligned room [0, size]."""
    sx, sy, sz = size
    c = (sx / 2, sy / 2, sz / 2)
    faces = [[(0, 0, 0), (sx, 0, 0), (sx, 0, sz), (0, 0, sz)], [(0, sy, 0), (0, sy, sz), (sx, sy, sz), (sx, sy, 0)],
             [(0, 0, 0), (0, sy, 0), (sx, sy, 0), (sx, 0, 0)], [(0, 0, sz), (sx, 0, sz), (sx, sy, sz), (0, sy, sz)],
             [(0, 0, 0), (0, 0, sz), (0, sy, sz), (0, sy, 0)], [(sx, 0, 0), (sx, sy, 0), (sx, sy, sz), (sx, 0, sz)]]
    for q in faces:
        q = [tuple(float(x) for x in p) for p in q]
        n = cb.cross(cb.sub(q[1], q[0]), cb.sub(q[2], q[0]))
        if cb.dot(n, cb.sub(c, cb.centroid(q))) < 0:
            q = list(reversed(q))
        m.quad(q, mat)


def tiny_emitter():
    """A 4 x 3 x 4 m room lit only by a 1 mm square emitter of radiance 1e6 (power pi W)."""
    m = Mesh()
    box_room(m, (4, 3, 4), 0)
    h, y = 0.0005, 2.9
    m.quad([(2 - h, y, 2 - h), (2 + h, y, 2 - h), (2 + h, y, 2 + h), (2 - h, y, 2 + h)], 1)  # faces down
    mats = [cb.material("white", (0.7, 0.7, 0.7)), cb.material("tiny light", (0.0, 0.0, 0.0), emission=(1e6, 1e6, 1e6))]
    return m.gltf(mats, (2.0, 1.5, 3.9), IDENTITY, yfov=1.3, name="tiny-emitter")


def scaled_cornell(scale):
    with open(os.path.join(os.path.dirname(HERE), "cornell-box", "cornell-box.gltf")) as f:
        doc = json.load(f)
    doc = copy.deepcopy(doc)
    doc["asset"]["generator"] = "nrad scenes/stress/make_stress_scenes.py"
    doc["nodes"][0]["scale"] = [scale] * 3
    doc["nodes"][1]["translation"] = [t * scale for t in doc["nodes"][1]["translation"]]
    doc["cameras"][0]["perspective"]["znear"] = 0.01 * scale
    return doc


def degenerate():
    """A lit floor with degenerate and sliver triangles, a tiny triangle alone in its voxel."""
    m = Mesh()
    m.quad([(0, 0, 0), (0, 0, 2), (2, 0, 2), (2, 0, 0)], 0)  # floor, facing up
    m.quad([(0.8, 1.99, 0.8), (1.2, 1.99, 0.8), (1.2, 1.99, 1.2), (0.8, 1.99, 1.2)], 1)  # light, facing down
    m.tri((0.5, 0.5, 0.5), (0.5, 0.5, 0.5), (0.5, 0.5, 0.5), 0)  # all three vertices equal
    m.tri((0.2, 0.3, 0.2), (0.6, 0.3, 0.2), (1.0, 0.3, 0.2), 0)  # collinear
    m.tri((0.1, 0.8, 1.5), (1.9, 0.8, 1.5), (1.0, 0.8 + 1e-6, 1.5), 0)  # sliver: 1.8 m long, 1 um wide
    m.tri((1.0, 1e-5, 0.1), (1.0, 1e-5, 1.9), (1.0 + 1e-6, 1e-5, 1.0), 0)  # sliver lying just above the floor
    s = 0.01  # a 1 cm triangle alone in the top corner voxel, facing down
    m.tri((1.9, 1.9, 1.9), (1.9 + s, 1.9, 1.9), (1.9, 1.9, 1.9 + s), 0)
    mats = [cb.material("white", (0.7, 0.7, 0.7)), cb.material("light", (0.0, 0.0, 0.0), emission=(10.0, 10.0, 10.0))]
    return m.gltf(mats, (1.0, 1.0, 3.5), IDENTITY, yfov=1.0, name="degenerate")


def radiance_span():
    """Five emissive tiles of radiance 1e-4, 1e-2, 1, 1e2 and 1e4 on a grey wall, lighting the floor in front."""
    m = Mesh()
    # A 5 x 1 x 1 grid over x in [-0.5, 4.5] puts tile i (centred at x = i) alone in voxel i.
    m.quad([(-0.5, 0, -0.5), (-0.5, 0, 3.0), (4.5, 0, 3.0), (4.5, 0, -0.5)], 0)  # floor, facing up
    m.quad([(-0.5, 0, -0.5), (4.5, 0, -0.5), (4.5, 1.5, -0.5), (-0.5, 1.5, -0.5)], 0)  # back wall, facing +z
    mats = [cb.material("grey", (0.5, 0.5, 0.5))]
    for i, radiance in enumerate([1e-4, 1e-2, 1.0, 1e2, 1e4]):
        x, h, y, z = float(i), 0.3, 0.5, -0.499
        m.quad([(x - h, y - h, z), (x + h, y - h, z), (x + h, y + h, z), (x - h, y + h, z)], 1 + i)  # facing +z
        mats.append(cb.material("tile %g" % radiance, (0.0, 0.0, 0.0), emission=(radiance,) * 3))
    return m.gltf(mats, (2.0, 1.2, 5.0), IDENTITY, yfov=1.0, name="radiance-span")


if __name__ == "__main__":
    for a, mean, p95 in (("0.5", 2, 5), ("0.9", 2, 5), ("0.99", 3, 8)):
        L = 1.0 / (1.0 - float(a))
        text = [t.format(a=a, L=L, n=L, mean=mean, p95=p95) for t in README["furnace"]]
        save("furnace-" + a, furnace(float(a)), *text)
    save("tiny-emitter", tiny_emitter(), *README["tiny-emitter"])
    save("cornell-box-scale-1e-3", scaled_cornell(1e-3), *[t.format(s="1e-3 (0.55 mm across)") for t in README["scaled"]])
    save("cornell-box-scale-1e4", scaled_cornell(1e4), *[t.format(s="1e4 (5.5 km across)") for t in README["scaled"]])
    save("degenerate", degenerate(), *README["degenerate"])
    save("radiance-span", radiance_span(), *README["radiance-span"])
