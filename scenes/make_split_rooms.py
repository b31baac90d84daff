#!/usr/bin/env python3
"""Writes scenes/split-rooms/split-rooms.gltf: the paper's light-selection test scene (Keller and Dahm, Sec. 4).

Four rooms in a 2 x 2 block (1 m cubes, walls 40 mm thick), open towards a camera that sees all of them.
Each opening is framed by a lintel and two pilasters; each room has two lights on the backs of its frame
(400 x 70 mm on the lintel, 70 x 400 mm on the outer pilaster), facing into the room: eight lights, two visible from any
point inside a room, none seen directly by the camera (so the image's noise is the lighting's, not the
anti-aliasing of bright emitter edges). Units: millimetres here, metres in the file.
Run from anywhere: python3 scenes/make_split_rooms.py
"""
import json, math, os, sys, base64

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import make_cornell_box as cb  # noqa: E402  (the glTF builder)

ROOM = 1000.0
WALL = 40.0  # partition thickness
DEPTH = 1000.0
WHITE = (0.7, 0.7, 0.7)
BACK_COLORS = [(0.7, 0.35, 0.3), (0.3, 0.6, 0.35), (0.3, 0.4, 0.7), (0.7, 0.65, 0.3)]
LIGHT_RADIANCE = (24.0, 22.0, 19.0)
FRAME = 100.0  # width of the lintel and pilasters framing each opening
FRAME_DEPTH = 40.0


def room_bounds(ix, iy):
    """Inner bounds of the room in column ix, row iy (x from 0 to 2 m, y from 0 to 2 m, z from -1 m to 0)."""
    x0 = ix * (ROOM + WALL / 2) + (WALL / 2 if ix else 0)
    y0 = iy * (ROOM + WALL / 2) + (WALL / 2 if iy else 0)
    return (x0, y0, -DEPTH), (x0 + ROOM, y0 + ROOM, 0.0)


def box_quads(lo, hi):
    """The six faces of an axis-aligned box, wound outwards."""
    c = tuple((a + b) / 2 for a, b in zip(lo, hi))
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = [
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)], [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)], [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
    ]
    return [cb.oriented(q, tuple(2 * m - n for m, n in zip(cb.centroid(q), c))) for q in faces]


def main():
    b = cb.Builder()
    materials = [cb.material("white", WHITE)]
    for i, col in enumerate(BACK_COLORS):
        materials.append(cb.material("back wall %d" % i, col))
    materials.append(cb.material("light", (0.8, 0.8, 0.8), emission=LIGHT_RADIANCE))
    light_mat = len(materials) - 1
    white_quads, lights, prims = [], [], []
    for iy in range(2):
        for ix in range(2):
            room = iy * 2 + ix
            (x0, y0, z0), (x1, y1, z1) = room_bounds(ix, iy)
            centre = ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2)
            inward = lambda q: cb.oriented(q, centre)
            white_quads += [inward(q) for q in [
                [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],  # floor
                [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],  # ceiling
                [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],  # left
                [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],  # right
            ]]
            prims.append(b.primitive([inward([(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)])], 1 + room))
            # A block on the floor (casts shadows from both lights).
            bx = x0 + (600 if ix == 0 else 150)
            block = box_quads((bx, y0, -700.0), (bx + 250, y0 + 300, -450.0))
            white_quads += block[:2] + block[3:]  # no bottom face
            # The opening is framed by a lintel and two pilasters, 40 mm deep; the lights sit on their backs,
            # facing into the room, so the camera in front never sees an emitter directly.
            lintel = box_quads((x0, y1 - FRAME, -FRAME_DEPTH), (x1, y1, 0.0))
            left = box_quads((x0, y0, -FRAME_DEPTH), (x0 + FRAME, y1 - FRAME, 0.0))
            right = box_quads((x1 - FRAME, y0, -FRAME_DEPTH), (x1, y1 - FRAME, 0.0))
            white_quads += [lintel[2], lintel[4], lintel[5], left[1], left[4], left[5], right[0], right[4], right[5]]
            lz = -FRAME_DEPTH - 1
            toward_room = (centre[0], centre[1], -DEPTH)
            # Light 1: 400 x 70 mm on the back of the lintel; its position along x varies per room.
            lx = x0 + (250 if room % 2 == 0 else 350)
            lights.append(cb.oriented([(lx, y1 - 85, lz), (lx + 400, y1 - 85, lz), (lx + 400, y1 - 15, lz),
                                       (lx, y1 - 15, lz)], toward_room))
            # Light 2: 70 x 400 mm on the back of the outer pilaster.
            px = x0 + 15 if ix == 0 else x1 - 85
            py = y0 + (250 if iy == 0 else 400)
            lights.append(cb.oriented([(px, py, lz), (px + 70, py, lz), (px + 70, py + 400, lz), (px, py + 400, lz)],
                                      toward_room))
    # The front faces of the partitions (seen by the camera between the rooms).
    mid = ROOM + WALL / 2
    white_quads.append([(ROOM, 0, 0), (ROOM + WALL, 0, 0), (ROOM + WALL, 2 * ROOM + WALL, 0), (ROOM, 2 * ROOM + WALL, 0)])
    white_quads.append([(0, ROOM, 0), (2 * ROOM + WALL, ROOM, 0), (2 * ROOM + WALL, ROOM + WALL, 0), (0, ROOM + WALL, 0)])
    white_quads[-2] = cb.oriented(white_quads[-2], (mid, mid, 1000.0))
    white_quads[-1] = cb.oriented(white_quads[-1], (mid, mid, 1000.0))
    prims.append(b.primitive(white_quads, 0))
    prims.append(b.primitive(lights, light_mat))

    size = 2 * ROOM + WALL
    yfov = 2 * math.atan((size / 2 + 60) / 3200.0)
    doc = {
        "asset": {"version": "2.0", "generator": "nrad scenes/make_split_rooms.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"name": "split-rooms", "nodes": [0, 1]}],
        "nodes": [
            {"name": "rooms", "mesh": 0},
            {"name": "camera", "camera": 0, "translation": [size / 2 * cb.MM, size / 2 * cb.MM, 3.2]},
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": yfov, "aspectRatio": 1.0, "znear": 0.01}}],
        "meshes": [{"name": "rooms", "primitives": prims}],
        "materials": materials,
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(b.blob)).decode()}],
    }
    folder = os.path.join(HERE, "split-rooms")
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "split-rooms.gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
