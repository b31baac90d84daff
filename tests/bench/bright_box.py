#!/usr/bin/env python3
"""Writes the Cornell box with bright walls (white 0.95, red 0.95/0.3/0.25, green 0.3/0.9/0.25): long paths,
where a start cut at a few segments misses much of the light (issue 16, docs/results.md).
Usage: tests/bench/bright_box.py OUT.gltf"""
import json
import os
import sys

if len(sys.argv) != 2:
    sys.exit(__doc__)
root = os.path.dirname(os.path.abspath(__file__))
scene = json.load(open(os.path.join(root, "..", "..", "scenes", "cornell-box", "cornell-box.gltf")))
colours = {"white": [0.95, 0.95, 0.95, 1.0], "red": [0.95, 0.3, 0.25, 1.0], "green": [0.3, 0.9, 0.25, 1.0]}
for m in scene["materials"]:
    if m["name"] in colours:
        m["pbrMetallicRoughness"]["baseColorFactor"] = colours[m["name"]]
with open(sys.argv[1], "w") as f:
    json.dump(scene, f)
