#!/usr/bin/env python3
"""Writes the glTF test corpus: malformed/ (each file broken in one stated way, each must be rejected with
exit code 3 and a message naming the file and containing `expect`) and valid/ (small edge cases that must
load). The expectations live in corpus.json, read by tests/cmd/cli_test.cpp.
Run: python3 tests/data/make_corpus.py"""
import base64, json, os, struct

HERE = os.path.dirname(os.path.abspath(__file__))


def gltf(positions, indices=None, extra=None, index_type=5125):
    """One triangle mesh primitive with data-URI buffers; `extra` patches the document."""
    blob = b"".join(struct.pack("<3f", *p) for p in positions)
    acc = [{"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3"}]
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(blob)}]
    prim = {"attributes": {"POSITION": 0}}
    if indices is not None:
        fmt = {5121: "<B", 5123: "<H", 5125: "<I"}[index_type]
        ib = b"".join(struct.pack(fmt, i) for i in indices)
        while len(blob) % 4:
            blob += b"\0"
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(ib)})
        blob += ib
        acc.append({"bufferView": 1, "componentType": index_type, "count": len(indices), "type": "SCALAR"})
        prim["indices"] = 1
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [prim]}], "accessors": acc, "bufferViews": views,
           "buffers": [{"byteLength": len(blob),
                        "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}]}
    if extra:
        extra(doc)
    return json.dumps(doc, indent=1) + "\n"


TRI = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
nan = float("nan")

MALFORMED = {
    "not-json.gltf": ('{ "asset": { "version": "2.0" }, this is not json', "not a valid glTF file"),
    "unsupported-required-extension.gltf": (
        gltf(TRI, extra=lambda d: d.update(extensionsUsed=["EXT_made_up"], extensionsRequired=["EXT_made_up"])),
        "requires extension EXT_made_up"),
    "missing-buffer.gltf": (
        gltf(TRI, extra=lambda d: d["buffers"][0].update(uri="does-not-exist.bin")), "does-not-exist.bin"),
    "index-out-of-range.gltf": (gltf(TRI, indices=[0, 1, 7]), "out of range"),
    "nonfinite-vertex.gltf": (gltf([(0, 0, 0), (1, nan, 0), (0, 1, 0)]), "non-finite position"),
    "accessor-past-end.gltf": (gltf(TRI, extra=lambda d: d["accessors"][0].update(count=300)), "past the end"),
    "node-cycle.gltf": (
        gltf(TRI, extra=lambda d: d.update(nodes=[{"mesh": 0, "children": [1]}, {"children": [0]}])), "cycle"),
    "missing-node.gltf": (gltf(TRI, extra=lambda d: d["scenes"][0].update(nodes=[5])), "node 5 does not exist"),
    "bad-material-index.gltf": (
        gltf(TRI, extra=lambda d: d["meshes"][0]["primitives"][0].update(material=3)), "refers to material 3"),
    "wrong-accessor-type.gltf": (gltf(TRI, extra=lambda d: d["accessors"][0].update(type="VEC2")),
                                 "expected 3"),
    "empty-file.gltf": ("", "not a valid glTF file"),
    "draco-bad-bufferview.gltf": (
        gltf(TRI, extra=lambda d: (d.update(extensionsUsed=["KHR_draco_mesh_compression"],
                                            extensionsRequired=["KHR_draco_mesh_compression"]),
                                   d["meshes"][0]["primitives"][0].update(extensions={"KHR_draco_mesh_compression": {
                                       "bufferView": 42, "attributes": {"POSITION": 0}}}))),
        "KHR_draco_mesh_compression refers to a bufferView that does not exist"),
    "draco-garbage.gltf": (
        gltf(TRI, extra=lambda d: (d.update(extensionsUsed=["KHR_draco_mesh_compression"],
                                            extensionsRequired=["KHR_draco_mesh_compression"]),
                                   d["accessors"][0].pop("bufferView"),
                                   d["meshes"][0]["primitives"][0].update(extensions={"KHR_draco_mesh_compression": {
                                       "bufferView": 0, "attributes": {"POSITION": 0}}}))),
        "has no valid bufferView"),
    "truncated-json.gltf": (gltf(TRI)[:200], "not a valid glTF file"),
    "infinite-vertex.gltf": (gltf([(0, 0, 0), (1, 0, 0), (0, float("inf"), 0)]), "non-finite position"),
    # Every triangle degenerate: nothing to render.
    "zero-triangles.gltf": (gltf([(0, 0, 0), (1, 1, 1), (2, 2, 2)]), "has no triangles"),
    "missing-image.gltf": (gltf(TRI, extra=lambda d: d.update(
        materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}], textures=[{"source": 0}],
        images=[{"uri": "does-not-exist.png"}]) or d["meshes"][0]["primitives"][0].update(material=0)),
        "does-not-exist.png"),
    "texture-not-an-image.gltf": (gltf(TRI, extra=lambda d: d.update(
        materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}], textures=[{"source": 0}],
        images=[{"uri": "data:image/png;base64," + base64.b64encode(b"this is not a PNG").decode()}])
        or d["meshes"][0]["primitives"][0].update(material=0)),
        "cannot decode image data for image[0]"),
}

VALID = {
    # Two triangles, the second with zero area: it must be dropped and counted, not fatal.
    "degenerate-triangle.gltf": gltf([(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 2, 2), (3, 3, 3), (4, 4, 4)]),
    # Non-indexed, no normals (flat normals generated), 8-bit indices elsewhere.
    "byte-indices.gltf": gltf(TRI, indices=[0, 1, 2], index_type=5121),
}

if __name__ == "__main__":
    os.makedirs(os.path.join(HERE, "malformed"), exist_ok=True)
    os.makedirs(os.path.join(HERE, "valid"), exist_ok=True)
    expectations = {}
    for name, (text, expect) in MALFORMED.items():
        with open(os.path.join(HERE, "malformed", name), "w") as f:
            f.write(text.replace("NaN", "NaN"))
        expectations[name] = expect
    for name, text in VALID.items():
        with open(os.path.join(HERE, "valid", name), "w") as f:
            f.write(text)
    with open(os.path.join(HERE, "malformed", "corpus.json"), "w") as f:
        json.dump(expectations, f, indent=1)
        f.write("\n")
