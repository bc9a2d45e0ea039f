#!/usr/bin/env python3
"""Writes experiments/scenes/strip-room.gltf (+ .bin): seed 004's many-light scene.

A closed room (10 x 3 x 10 m, grey walls, a wooden-brown floor) with four low boxes on the
floor and an LED strip running round the top of the walls and over the boxes: thousands of
small emissive quads (two triangles each) in four colours, facing down. A glTF camera stands
by one wall looking across the room. Deterministic; no dependencies.

Run: python3 tools/strip_room.py [OUT.gltf]
"""
import base64
import json
import math
import struct
import sys

out = sys.argv[1] if len(sys.argv) > 1 else "experiments/scenes/strip-room.gltf"

meshes = {}  # material -> (positions, normals, indices)


def add_quad(material, corners, normal):
    pos, nor, idx = meshes.setdefault(material, ([], [], []))
    base = len(pos)
    pos.extend(corners)
    nor.extend([normal] * 4)
    idx.extend([base, base + 1, base + 2, base, base + 2, base + 3])


def add_box(material, lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = [
        ([(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)], (0, 1, 0)),
        ([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, -1, 0)),
        ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, 1)),
        ([(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)], (0, 0, -1)),
        ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (1, 0, 0)),
        ([(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)], (-1, 0, 0)),
    ]
    for corners, n in faces:
        add_quad(material, corners, n)


# The room, seen from inside: each face's quad wound to face into the room.
H, R = 3.0, 5.0
add_quad(1, [(-R, 0, -R), (-R, 0, R), (R, 0, R), (R, 0, -R)], (0, 1, 0))  # floor
add_quad(0, [(-R, H, -R), (R, H, -R), (R, H, R), (-R, H, R)], (0, -1, 0))  # ceiling
add_quad(0, [(-R, 0, -R), (R, 0, -R), (R, H, -R), (-R, H, -R)], (0, 0, 1))  # back
add_quad(0, [(-R, 0, R), (-R, H, R), (R, H, R), (R, 0, R)], (0, 0, -1))  # front
add_quad(0, [(-R, 0, -R), (-R, H, -R), (-R, H, R), (-R, 0, R)], (1, 0, 0))  # left
add_quad(0, [(R, 0, -R), (R, 0, R), (R, H, R), (R, H, -R)], (-1, 0, 0))  # right

# Four low boxes (tables).
boxes = [((-3.0, 0, -3.0), (-1.5, 0.8, -2.0)), ((1.0, 0, -3.5), (3.0, 0.9, -2.5)),
         ((-2.5, 0, 0.5), (-1.0, 0.7, 2.0)), ((1.5, 0, 0.0), (2.5, 1.2, 1.0))]
for lo, hi in boxes:
    add_box(2, lo, hi)

# The LED strip: quads of 2 cm every 2.5 cm, 2 cm below the ceiling along the walls, and
# 1 cm under each box's top edge all round.
S, STEP = 0.01, 0.025
count = 0


def led(x, y, z):
    global count
    add_quad(3 + count % 4, [(x - S, y, z - S), (x + S, y, z - S), (x + S, y, z + S), (x - S, y, z + S)],
             (0, -1, 0))
    count += 1


n = int(2 * (R - 0.1) / STEP)
for i in range(n + 1):
    t = -(R - 0.1) + i * STEP
    for x, z in ((t, -(R - 0.1)), (t, R - 0.1), (-(R - 0.1), t), (R - 0.1, t)):
        led(x, H - 0.02, z)
for (x0, _, z0), (x1, y1, z1) in boxes:
    for along in (0, 1):
        a0, a1 = (x0, x1) if along == 0 else (z0, z1)
        m = int((a1 - a0) / STEP)
        for i in range(m + 1):
            a = a0 + i * STEP
            for b in ((z0 - 0.03, z1 + 0.03) if along == 0 else (x0 - 0.03, x1 + 0.03)):
                x, z = (a, b) if along == 0 else (b, a)
                led(x, y1 - 0.01, z)

materials = [
    {"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1], "metallicFactor": 0, "roughnessFactor": 0.9}},
    {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.45, 0.3, 0.2, 1], "metallicFactor": 0, "roughnessFactor": 0.4}},
    {"name": "box", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.35, 0.5, 1], "metallicFactor": 0, "roughnessFactor": 0.6}},
]
for name, colour in (("led-warm", [1.0, 0.7, 0.4]), ("led-cold", [0.5, 0.7, 1.0]),
                     ("led-red", [1.0, 0.15, 0.1]), ("led-green", [0.2, 1.0, 0.3])):
    materials.append({"name": name, "emissiveFactor": colour, "doubleSided": True,
                      "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 40.0}},
                      "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.1, 0.1, 1], "metallicFactor": 0}})

binary = bytearray()
accessors, views, gl_meshes, nodes = [], [], [], []
for material in sorted(meshes):
    pos, nor, idx = meshes[material]
    prim = {"material": material, "attributes": {}}
    for name, data, fmt, kind, comp in (("POSITION", pos, "3f", "VEC3", 5126), ("NORMAL", nor, "3f", "VEC3", 5126)):
        offset = len(binary)
        for v in data:
            binary += struct.pack("<" + fmt, *v)
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(binary) - offset})
        acc = {"bufferView": len(views) - 1, "componentType": comp, "count": len(data), "type": kind}
        if name == "POSITION":
            acc["min"] = [min(v[k] for v in data) for k in range(3)]
            acc["max"] = [max(v[k] for v in data) for k in range(3)]
        accessors.append(acc)
        prim["attributes"][name] = len(accessors) - 1
    offset = len(binary)
    binary += struct.pack("<%dI" % len(idx), *idx)
    views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(binary) - offset})
    accessors.append({"bufferView": len(views) - 1, "componentType": 5125, "count": len(idx), "type": "SCALAR"})
    prim["indices"] = len(accessors) - 1
    gl_meshes.append({"name": materials[material]["name"], "primitives": [prim]})
    nodes.append({"mesh": len(gl_meshes) - 1})

# Camera at (0, 1.6, 4.5) looking toward (0, 1.0, -2): rotation about x by the pitch.
pitch = math.atan2(1.6 - 1.0, 4.5 + 2.0)
nodes.append({"camera": 0, "translation": [0, 1.6, 4.5],
              "rotation": [-math.sin(pitch / 2), 0, 0, math.cos(pitch / 2)]})
bin_name = out.rsplit("/", 1)[-1].replace(".gltf", ".bin")
gltf = {
    "asset": {"version": "2.0", "generator": "pathlight tools/strip_room.py"},
    "extensionsUsed": ["KHR_materials_emissive_strength"],
    "scene": 0,
    "scenes": [{"nodes": list(range(len(nodes)))}],
    "nodes": nodes,
    "meshes": gl_meshes,
    "materials": materials,
    "cameras": [{"type": "perspective", "perspective": {"yfov": math.radians(70), "aspectRatio": 16 / 9, "znear": 0.05}}],
    "buffers": [{"uri": bin_name, "byteLength": len(binary)}],
    "bufferViews": views,
    "accessors": accessors,
}
with open(out, "w") as f:
    json.dump(gltf, f, indent=1)
with open(out.rsplit("/", 1)[0] + "/" + bin_name if "/" in out else bin_name, "wb") as f:
    f.write(binary)
print(f"{out}: {count} LED quads ({2 * count} emissive triangles), {len(binary)} bytes of buffer")
