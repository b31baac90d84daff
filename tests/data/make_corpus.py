#!/usr/bin/env python3
"""Writes the glTF test corpus: malformed/ (each file broken in one stated way, each must be rejected with
exit code 3 and a message naming the file and containing `expect`) and valid/ (small edge cases that must
load). The expectations live in corpus.json, read by tests/cmd/cli_test.cpp.
Run: python3 tests/data/make_corpus.py"""
import base64, json, os, struct, zlib

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


def png_header_only(width, height):
    """A PNG whose header claims width x height, with one tiny IDAT: enough for a header check, never decodable
    at that size. (The hostile file this stands for held a real 16384 x 16384 PNG in 348 KB.)"""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))


def textured(image_uri):
    return lambda d: d.update(materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                              textures=[{"source": 0}], images=[{"uri": image_uri}]) or \
        d["meshes"][0]["primitives"][0].update(material=0)


def dag(depth):
    """Node i lists node i + 1 twice as its child: 2^depth instances of the mesh if it were flattened."""
    return lambda d: d.update(nodes=[{"children": [i + 1, i + 1]} for i in range(depth)] + [{"mesh": 0}])

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
        "its Draco data cannot be decoded"),
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
    # Hostile input (issue 37): sizes and offsets chosen to wrap 64-bit arithmetic, graphs that grow as 2^depth,
    # an image whose decoding alone would take gigabytes. Each crashed, read outside its buffer or ran out of
    # memory before the importer checked it; they are also in the glTF fuzzer's corpus.
    "accessor-count-wraps.gltf": (gltf(TRI, extra=lambda d: d["accessors"][0].update(count=12297829382473034411)),
                                  "reads past the end"),
    "accessor-offset-wraps.gltf": (gltf(TRI, extra=lambda d: d["accessors"][0].update(byteOffset=2**64 - 8)),
                                   "reads past the end"),
    "bytestride-wraps.gltf": (gltf(TRI, extra=lambda d: d["bufferViews"][0].update(byteStride=6148914691236517206)),
                              "byteStride"),
    "node-dag.gltf": (gltf(TRI, extra=dag(30)), "node 1 has two parents"),
    "root-is-a-child.gltf": (gltf(TRI, extra=lambda d: (d.update(nodes=[{"children": [1]}, {"mesh": 0}]),
                                                        d["scenes"][0].update(nodes=[0, 1]))),
                             "node 1 is a root of the scene and a child of node 0"),
    "huge-image.gltf": (gltf(TRI, extra=textured("data:image/png;base64," +
                                                 base64.b64encode(png_header_only(16384, 16384)).decode())),
                        "image 0 is 16384 x 16384 pixels, more than the limit of 67108864 (--max-texture-pixels)"),
}

VALID = {
    # Two triangles, the second with zero area: it must be dropped and counted, not fatal.
    "degenerate-triangle.gltf": gltf([(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 2, 2), (3, 3, 3), (4, 4, 4)]),
    # Non-indexed, no normals (flat normals generated), 8-bit indices elsewhere.
    "byte-indices.gltf": gltf(TRI, indices=[0, 1, 2], index_type=5121),
}

def glb(text):
    """The .gltf text as a .glb whose JSON chunk holds it (its data-URI buffers stay in the JSON)."""
    body = text.encode()
    body += b" " * (-len(body) % 4)
    return struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(body)) + struct.pack("<I4s", len(body), b"JSON") + body


# The glTF fuzzer's own seeds (tests/fuzz/gltf-corpus): the hostile inputs and a valid file as .glb, so that
# mutations start from the binary container too (the .gltf forms are seeded from malformed/ and valid/).
FUZZ_SEEDS = ["accessor-count-wraps.gltf", "accessor-offset-wraps.gltf", "bytestride-wraps.gltf", "node-dag.gltf",
              "huge-image.gltf"]

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
    fuzz = os.path.join(HERE, "..", "fuzz", "gltf-corpus")
    os.makedirs(fuzz, exist_ok=True)
    for name in FUZZ_SEEDS:
        with open(os.path.join(fuzz, name.replace(".gltf", ".glb")), "wb") as f:
            f.write(glb(MALFORMED[name][0]))
    with open(os.path.join(fuzz, "byte-indices.glb"), "wb") as f:
        f.write(glb(VALID["byte-indices.gltf"]))
    with open(os.path.join(HERE, "malformed", "corpus.json"), "w") as f:
        json.dump(expectations, f, indent=1)
        f.write("\n")
