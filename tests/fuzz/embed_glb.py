#!/usr/bin/env python3
"""Writes a .gltf whose one buffer is an external file as a .glb with that buffer as its BIN chunk: a seed the
glTF fuzzer (which reads no external files) can mutate, e.g. a real Draco stream.
Usage: embed_glb.py IN.gltf OUT.glb"""
import json, os, struct, sys

src, out = sys.argv[1], sys.argv[2]
doc = json.load(open(src))
if len(doc.get("buffers", [])) != 1 or "uri" not in doc["buffers"][0]:
    sys.exit(f"{src}: expected one buffer with a uri")
blob = open(os.path.join(os.path.dirname(src), doc["buffers"][0].pop("uri")), "rb").read()
blob += b"\0" * (-len(blob) % 4)
text = json.dumps(doc).encode()
text += b" " * (-len(text) % 4)
body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
open(out, "wb").write(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
