#!/usr/bin/env python3
"""Writes the interior test scenes of issue 38 (what the eye sees in real interiors):

- scenes/doorway-rooms/doorway-rooms.gltf: two rooms sharing a 20 mm wall at 0.37 of the width (on no voxel
  face of any grid up to 8), room A lit by a 0.5 x 0.5 m emissive quad 10 mm under its ceiling, room B dark
  except through a 0.5 x 1.6 m doorway; every surface grey Lambertian (0.6), so any colour in an image of it
  is an error. The camera stands in room B and looks at the shared wall and the doorway.
- scenes/sealed-rooms/sealed-rooms.gltf: the same without the doorway: room B must be exactly black.

Units: millimetres here, metres in the file. Run from anywhere: python3 scenes/make_interiors.py
"""
import base64, json, math, os, sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import make_cornell_box as cb  # noqa: E402  (the glTF builder)

WIDTH, HEIGHT, DEPTH = 6000.0, 2600.0, 4000.0  # x, y, z of the whole interior
WALL_X = 0.37 * WIDTH  # the shared wall's room-A face
WALL = 20.0
DOOR_Z = (1750.0, 2250.0)  # the doorway: 0.5 m wide, 1.6 m high
DOOR_H = 1600.0
LIGHT_SIZE = 500.0
LIGHT_DROP = 10.0  # below room A's ceiling
GREY = (0.6, 0.6, 0.6)
LIGHT_RADIANCE = (40.0, 40.0, 40.0)


def facing(quad, normal):
    """The quad wound so that its normal points along `normal`."""
    c = cb.centroid(quad)
    return cb.oriented(quad, tuple(a + 1000.0 * n for a, n in zip(c, normal)))


def room(x0, x1):
    """Floor, ceiling, and the front, back and outer walls of a room spanning x0..x1, facing in."""
    return [
        facing([(x0, 0, 0), (x1, 0, 0), (x1, 0, DEPTH), (x0, 0, DEPTH)], (0, 1, 0)),
        facing([(x0, HEIGHT, 0), (x1, HEIGHT, 0), (x1, HEIGHT, DEPTH), (x0, HEIGHT, DEPTH)], (0, -1, 0)),
        facing([(x0, 0, 0), (x1, 0, 0), (x1, HEIGHT, 0), (x0, HEIGHT, 0)], (0, 0, 1)),
        facing([(x0, 0, DEPTH), (x1, 0, DEPTH), (x1, HEIGHT, DEPTH), (x0, HEIGHT, DEPTH)], (0, 0, -1)),
    ]


def wall_face(x, normal, door):
    """One face of the shared wall at x, with the doorway cut out if `door`."""
    rect = lambda z0, z1, y0, y1: facing([(x, y0, z0), (x, y0, z1), (x, y1, z1), (x, y1, z0)], normal)
    if not door:
        return [rect(0, DEPTH, 0, HEIGHT)]
    return [rect(0, DOOR_Z[0], 0, HEIGHT), rect(DOOR_Z[1], DEPTH, 0, HEIGHT), rect(DOOR_Z[0], DOOR_Z[1], DOOR_H, HEIGHT)]


def write(name, door):
    b = cb.Builder()
    materials = [cb.material("grey", GREY), cb.material("light", GREY, emission=LIGHT_RADIANCE)]
    a0, a1 = 0.0, WALL_X
    b0, b1 = WALL_X + WALL, WIDTH
    grey = room(a0, a1) + room(b0, b1)
    grey.append(facing([(a0, 0, 0), (a0, 0, DEPTH), (a0, HEIGHT, DEPTH), (a0, HEIGHT, 0)], (1, 0, 0)))  # room A's outer wall
    grey.append(facing([(b1, 0, 0), (b1, 0, DEPTH), (b1, HEIGHT, DEPTH), (b1, HEIGHT, 0)], (-1, 0, 0)))  # room B's
    grey += wall_face(a1, (-1, 0, 0), door) + wall_face(b0, (1, 0, 0), door)
    if door:  # the doorway's reveal: its two sides and its head, 20 mm deep
        grey.append(facing([(a1, 0, DOOR_Z[0]), (b0, 0, DOOR_Z[0]), (b0, DOOR_H, DOOR_Z[0]), (a1, DOOR_H, DOOR_Z[0])], (0, 0, 1)))
        grey.append(facing([(a1, 0, DOOR_Z[1]), (b0, 0, DOOR_Z[1]), (b0, DOOR_H, DOOR_Z[1]), (a1, DOOR_H, DOOR_Z[1])], (0, 0, -1)))
        grey.append(facing([(a1, DOOR_H, DOOR_Z[0]), (b0, DOOR_H, DOOR_Z[0]), (b0, DOOR_H, DOOR_Z[1]), (a1, DOOR_H, DOOR_Z[1])],
                           (0, -1, 0)))
    cx, cz, ly = (a0 + a1) / 2, DEPTH / 2, HEIGHT - LIGHT_DROP
    h = LIGHT_SIZE / 2
    light = facing([(cx - h, ly, cz - h), (cx + h, ly, cz - h), (cx + h, ly, cz + h), (cx - h, ly, cz + h)], (0, -1, 0))
    prims = [b.primitive(grey, 0), b.primitive([light], 1)]
    # The camera in room B, 1.5 m high, 0.6 m from its outer wall, looking along -x at the shared wall (glTF
    # cameras look down -Z: turned +90 degrees about Y), a little towards the doorway's side.
    yaw = math.radians(90.0 + 8.0)
    camera = {"name": "camera", "camera": 0, "translation": [(b1 - 600.0) * cb.MM, 1500.0 * cb.MM, 2600.0 * cb.MM],
              "rotation": [0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2)]}
    doc = {
        "asset": {"version": "2.0", "generator": "nrad scenes/make_interiors.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"name": name, "nodes": [0, 1]}],
        "nodes": [{"name": "rooms", "mesh": 0}, camera],
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": math.radians(60.0), "aspectRatio": 4.0 / 3.0, "znear": 0.01}}],
        "meshes": [{"name": "rooms", "primitives": prims}],
        "materials": materials,
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(b.blob)).decode()}],
    }
    folder = os.path.join(HERE, name)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name + ".gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    write("doorway-rooms", door=True)
    write("sealed-rooms", door=False)
