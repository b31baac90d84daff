#!/usr/bin/env python3
"""Writes the interior test scenes of issue 38 (what the eye sees in real interiors):

- scenes/doorway-rooms/doorway-rooms.gltf: two rooms sharing a 20 mm wall at 0.37 of the width (on no voxel
  face of any grid up to 8), room A lit by a 0.5 x 0.5 m emissive quad 10 mm under its ceiling, room B dark
  except through a 0.5 x 1.6 m doorway; every surface grey Lambertian (0.6), so any colour in an image of it
  is an error. The camera stands in room B and looks at the shared wall and the doorway.
- scenes/sealed-rooms/sealed-rooms.gltf: the same without the doorway: room B must be exactly black.
- scenes/sky-room/sky-room.gltf: a room of 5 x 3 x 5 m with 200 mm walls, lit only by the sky (it has no light
  of its own: nrad gives it the default sky) through a door and two windows, a table and a cabinet inside,
  every surface grey (0.6). The camera stands inside and sees the ceiling, two walls and the floor.
- scenes/living-room/living-room.gltf: a 6 x 2.8 x 5 m room with a wide window, lit by a 10,000 lux sun (a
  KHR_lights_punctual directional light) through it; a table with a glossy black top faces the window, a sofa
  and a cabinet, the rest grey (0.6). The camera looks across the table at the window.

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


def write_gltf(name, builder, prims, materials, camera, yfov_degrees, sun=None):
    """Writes scenes/NAME/NAME.gltf: one mesh of `prims`, the camera node `camera`, and with sun = (direction
    towards the sun, illuminance in lux) a KHR_lights_punctual directional light."""
    doc = {
        "asset": {"version": "2.0", "generator": "nrad scenes/make_interiors.py"},
        "extensionsUsed": sorted({e for m in materials for e in m.get("extensions", {})}),
        "scene": 0,
        "scenes": [{"name": name, "nodes": [0, 1]}],
        "nodes": [{"name": name, "mesh": 0}, camera],
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": math.radians(yfov_degrees), "aspectRatio": 4.0 / 3.0, "znear": 0.01}}],
        "meshes": [{"name": name, "primitives": prims}],
        "materials": materials,
        "accessors": builder.accessors,
        "bufferViews": builder.views,
        "buffers": [{"byteLength": len(builder.blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(builder.blob)).decode()}],
    }
    if sun:
        towards, lux = sun
        n = math.sqrt(sum(c * c for c in towards))
        d = [-c / n for c in towards]  # the light travels along d; a glTF light shines down its node's -Z
        axis = (d[1], -d[0], 0.0)  # (0, 0, -1) x d
        s_ = math.sqrt(axis[0] ** 2 + axis[1] ** 2)
        angle = math.acos(max(-1.0, min(1.0, -d[2])))
        rot = [axis[0] / s_ * math.sin(angle / 2), axis[1] / s_ * math.sin(angle / 2), 0.0, math.cos(angle / 2)]
        doc["extensionsUsed"] = sorted(set(doc["extensionsUsed"]) | {"KHR_lights_punctual"})
        doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"name": "sun", "type": "directional", "intensity": lux}]}}
        doc["nodes"].append({"name": "sun", "rotation": rot, "extensions": {"KHR_lights_punctual": {"light": 0}}})
        doc["scenes"][0]["nodes"].append(2)
    folder = os.path.join(HERE, name)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name + ".gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


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
    write_gltf(name, b, prims, materials, camera, 60.0)


def wall_with_openings(axis, at, normal, u_range, v_range, openings):
    """A wall in the plane coordinate[axis] = at, spanning u_range x v_range (u, v: the other two axes in
    order), less the rectangular openings [(u0, u1, v0, v1)], as a grid of rectangles, facing `normal`."""
    us = sorted({u_range[0], u_range[1]} | {o[0] for o in openings} | {o[1] for o in openings})
    vs = sorted({v_range[0], v_range[1]} | {o[2] for o in openings} | {o[3] for o in openings})
    others = [k for k in range(3) if k != axis]
    quads = []
    for i in range(len(us) - 1):
        for j in range(len(vs) - 1):
            cu, cv = (us[i] + us[i + 1]) / 2, (vs[j] + vs[j + 1]) / 2
            if any(o[0] < cu < o[1] and o[2] < cv < o[3] for o in openings):
                continue
            corners = []
            for u, v in [(us[i], vs[j]), (us[i + 1], vs[j]), (us[i + 1], vs[j + 1]), (us[i], vs[j + 1])]:
                p = [0.0, 0.0, 0.0]
                p[axis], p[others[0]], p[others[1]] = at, u, v
                corners.append(tuple(p))
            quads.append(facing(corners, normal))
    return quads


def box(lo, hi, bottom=False):
    """An axis-aligned box's faces, outwards (without its bottom unless asked)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    q = [facing([(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, 1, 0)),
         facing([(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (-1, 0, 0)),
         facing([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (1, 0, 0)),
         facing([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], (0, 0, -1)),
         facing([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, 1))]
    if bottom:
        q.append(facing([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, -1, 0)))
    return q


def shell(X, Y, Z, T, door, windows):
    """A room of inner size X x Y x Z with walls T thick, a door (x0, x1, y0, y1) in the z = Z wall and windows
    (y0, y1, z0, z1) in the x = 0 wall: the inside faces, the outside of the shell, the openings' reveals."""
    grey = []
    # Inside faces, then the outside of the shell, then each opening's reveal through the thickness.
    grey.append(facing([(0, 0, 0), (X, 0, 0), (X, 0, Z), (0, 0, Z)], (0, 1, 0)))
    grey.append(facing([(0, Y, 0), (X, Y, 0), (X, Y, Z), (0, Y, Z)], (0, -1, 0)))
    grey += wall_with_openings(0, 0.0, (1, 0, 0), (0.0, Y), (0.0, Z), windows)
    grey += wall_with_openings(0, X, (-1, 0, 0), (0.0, Y), (0.0, Z), [])
    grey += wall_with_openings(2, 0.0, (0, 0, 1), (0.0, X), (0.0, Y), [])
    grey += wall_with_openings(2, Z, (0, 0, -1), (0.0, X), (0.0, Y), [door])
    grey.append(facing([(-T, -T, -T), (X + T, -T, -T), (X + T, -T, Z + T), (-T, -T, Z + T)], (0, -1, 0)))
    grey.append(facing([(-T, Y + T, -T), (X + T, Y + T, -T), (X + T, Y + T, Z + T), (-T, Y + T, Z + T)], (0, 1, 0)))
    grey += wall_with_openings(0, -T, (-1, 0, 0), (-T, Y + T), (-T, Z + T), windows)
    grey += wall_with_openings(0, X + T, (1, 0, 0), (-T, Y + T), (-T, Z + T), [])
    grey += wall_with_openings(2, -T, (0, 0, -1), (-T, X + T), (-T, Y + T), [])
    grey += wall_with_openings(2, Z + T, (0, 0, 1), (-T, X + T), (-T, Y + T), [(door[0], door[1], -T, door[3])])
    # The shell's edges between inside and outside where the floor and walls meet the openings: reveals.
    for (y0, y1, z0, z1) in windows:
        grey.append(facing([(-T, y0, z0), (0, y0, z0), (0, y0, z1), (-T, y0, z1)], (0, 1, 0)))
        grey.append(facing([(-T, y1, z0), (0, y1, z0), (0, y1, z1), (-T, y1, z1)], (0, -1, 0)))
        grey.append(facing([(-T, y0, z0), (0, y0, z0), (0, y1, z0), (-T, y1, z0)], (0, 0, 1)))
        grey.append(facing([(-T, y0, z1), (0, y0, z1), (0, y1, z1), (-T, y1, z1)], (0, 0, -1)))
    x0, x1, y1 = door[0], door[1], door[3]
    grey.append(facing([(x0, y1, Z), (x1, y1, Z), (x1, y1, Z + T), (x0, y1, Z + T)], (0, -1, 0)))
    grey.append(facing([(x0, 0, Z), (x0, y1, Z), (x0, y1, Z + T), (x0, 0, Z + T)], (1, 0, 0)))
    grey.append(facing([(x1, 0, Z), (x1, y1, Z), (x1, y1, Z + T), (x1, 0, Z + T)], (-1, 0, 0)))
    grey.append(facing([(x0, -T, Z), (x1, -T, Z), (x1, -T, Z + T), (x0, -T, Z + T)], (0, 1, 0)))  # the door's sill
    grey.append(facing([(x0, -T, Z), (x1, -T, Z), (x1, 0, Z), (x0, 0, Z)], (0, 0, 1)))  # the floor's edge in the door
    return grey


def look(yaw_degrees, pitch_degrees):
    """A glTF camera's rotation: yaw about Y, then pitch in the camera's frame (q = qy * qx)."""
    yaw, pitch = math.radians(yaw_degrees), math.radians(pitch_degrees)
    qy = (0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2))
    qx = (math.sin(pitch / 2), 0.0, 0.0, math.cos(pitch / 2))
    return [qy[3] * qx[0] + qy[0] * qx[3] + qy[1] * qx[2] - qy[2] * qx[1],
            qy[3] * qx[1] - qy[0] * qx[2] + qy[1] * qx[3] + qy[2] * qx[0],
            qy[3] * qx[2] + qy[0] * qx[1] - qy[1] * qx[0] + qy[2] * qx[3],
            qy[3] * qx[3] - qy[0] * qx[0] - qy[1] * qx[1] - qy[2] * qx[2]]


def write_sky_room():
    X, Y, Z, T = 5000.0, 3000.0, 5000.0, 200.0  # inner size and wall thickness
    door = (1800.0, 2700.0, 0.0, 2100.0)  # in the z = Z wall (u = x, v = y)
    windows = [(800.0, 2000.0, 900.0, 1900.0), (2800.0, 4000.0, 900.0, 1900.0)]  # in the x = 0 wall (u = y, v = z)
    windows = [(w[2], w[3], w[0], w[1]) for w in windows]  # as (y0, y1, z0, z1)
    grey = shell(X, Y, Z, T, door, windows)
    # A table (top on four legs) and a cabinet.
    grey += box((2000.0, 700.0, 1800.0), (3400.0, 750.0, 2800.0), bottom=True)
    for lx, lz in [(2050, 1850), (3300, 1850), (2050, 2700), (3300, 2700)]:
        grey += box((float(lx), 0.0, float(lz)), (lx + 50.0, 700.0, lz + 50.0))
    grey += box((4300.0, 0.0, 600.0), (4900.0, 1800.0, 1600.0))
    b = cb.Builder()
    prims = [b.primitive(grey, 0)]
    # The camera by the wall opposite the windows, 1.6 m high, looking towards the windows and the door's
    # corner, a little down (yaw about Y, then pitch).
    q = look(55.0, -12.0)  # looking along (-0.82, 0, -0.57), then 12 degrees down
    camera = {"name": "camera", "camera": 0, "translation": [4600.0 * cb.MM, 1600.0 * cb.MM, 4400.0 * cb.MM], "rotation": list(q)}
    write_gltf("sky-room", b, prims, [cb.material("grey", GREY)], camera, 65.0)


def write_living_room():
    X, Y, Z, T = 6000.0, 2800.0, 5000.0, 200.0
    door = (4600.0, 5500.0, 0.0, 2100.0)  # in the z = Z wall
    windows = [(700.0, 2300.0, 1200.0, 3800.0)]  # one wide window in the x = 0 wall, as (y0, y1, z0, z1)
    grey = shell(X, Y, Z, T, door, windows)
    # A sofa and a low cabinet, grey.
    grey += box((4200.0, 0.0, 800.0), (5200.0, 800.0, 3200.0))
    grey += box((2200.0, 0.0, 4300.0), (3800.0, 600.0, 4800.0))
    # The table facing the window: a glossy black top (roughness 0.15, full specular) on four grey legs.
    top = box((1200.0, 720.0, 1800.0), (2600.0, 760.0, 3200.0), bottom=True)
    legs = []
    for lx, lz in [(1260, 1860), (2500, 1860), (1260, 3100), (2500, 3100)]:
        legs += box((float(lx), 0.0, float(lz)), (lx + 40.0, 720.0, lz + 40.0))
    b = cb.Builder()
    prims = [b.primitive(grey + legs, 0), b.primitive(top, 1)]
    materials = [cb.material("grey", GREY), cb.material("glossy table", (0.04, 0.04, 0.04), roughness=0.15, specular=1.0)]
    # The camera at the back of the room, 1.5 m high, looking at the table and the window, a little down.
    camera = {"name": "camera", "camera": 0, "translation": [5600.0 * cb.MM, 1500.0 * cb.MM, 3900.0 * cb.MM],
              "rotation": look(75.0, -14.0)}
    # A low afternoon sun through the window: onto the floor, the table and the wall opposite.
    write_gltf("living-room", b, prims, materials, camera, 65.0, sun=((-0.75, 0.55, 0.3), 10000.0))


if __name__ == "__main__":
    write("doorway-rooms", door=True)
    write("sealed-rooms", door=False)
    write_sky_room()
    write_living_room()
