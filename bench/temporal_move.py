#!/usr/bin/env python3
"""Write the camera move of docs/temporal.md: scenes/default.gltf with its camera
`main` trucking sideways.

The output is the default scene's glTF unchanged (its embedded buffers, nodes,
materials, cameras) plus one more buffer and an animation `truck` that moves the
node `camera_main` along its own right axis (x of its rotation) at a constant
speed, LINEAR between two keys: frame F (at 24 fps, time F/24 s) places the
camera at p0 + DOLLY * forward + (F - FRAMES/2) * STEP * right, p0 the file's
own translation. Its rotation does not change: a truck, so near things slide
across the frame faster than far ones (parallax, disocclusion). DOLLY brings the
camera closer than the file's framing, so that the columns, the bowl and the
walls cross the image's edges during the move (where a depth buffer has nothing
to say and the guard band matters).

At 320x180 (yfov 0.7: 246.6 px per unit at unit depth) with DOLLY 3.5 and STEP
0.04, a point at the origin (depth 4.3) moves 2.3 px a frame, the tall column
(3.75) 2.6 px, the crate (5.6) 1.75 px, the walls' corner (6.7) 1.5 px.

Usage: bench/temporal_move.py OUT.gltf [--frames N] [--step UNITS] [--dolly UNITS] [--fps FPS]
Only the standard library; the output is a pure function of the arguments.
"""

import argparse
import base64
import json
import os
import struct
import sys


def rotate(q, v):
    """v rotated by the unit quaternion q = (x, y, z, w)."""
    x, y, z, w = q
    # t = 2 q.xyz x v; v' = v + w t + q.xyz x t
    tx = 2 * (y * v[2] - z * v[1])
    ty = 2 * (z * v[0] - x * v[2])
    tz = 2 * (x * v[1] - y * v[0])
    return (v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz), v[2] + w * tz + (x * ty - y * tx))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("output")
    ap.add_argument("--frames", type=int, default=16, help="the move spans frames 0..FRAMES (default 16)")
    ap.add_argument("--step", type=float, default=0.04, help="scene units the camera moves per frame (default 0.04)")
    ap.add_argument("--dolly", type=float, default=3.5,
                    help="scene units the whole move is moved forward, along the camera's view (default 3.5)")
    ap.add_argument("--fps", type=float, default=24.0, help="frames per second the keys are timed at (default 24)")
    ap.add_argument("--scene", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes",
                                                    "default.gltf"))
    a = ap.parse_args()
    if a.frames < 1:
        sys.exit("temporal_move: --frames must be at least 1")
    with open(a.scene) as f:
        doc = json.load(f)
    cam = next(i for i, n in enumerate(doc["nodes"]) if n.get("name") == "camera_main")
    node = doc["nodes"][cam]
    p0 = node["translation"]
    right = rotate(node["rotation"], (1.0, 0.0, 0.0))
    forward = rotate(node["rotation"], (0.0, 0.0, -1.0))
    keys = []
    for frame in (0, a.frames):
        s = (frame - a.frames / 2) * a.step
        keys.append((frame / a.fps, [p0[k] + s * right[k] + a.dolly * forward[k] for k in range(3)]))
    times = struct.pack("<2f", keys[0][0], keys[1][0])
    values = struct.pack("<6f", *keys[0][1], *keys[1][1])
    blob = times + values
    buf = len(doc["buffers"])
    doc["buffers"].append({"byteLength": len(blob),
                           "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()})
    views = len(doc["bufferViews"])
    doc["bufferViews"] += [{"buffer": buf, "byteOffset": 0, "byteLength": 8},
                           {"buffer": buf, "byteOffset": 8, "byteLength": 24}]
    acc = len(doc["accessors"])
    tmin, tmax = struct.unpack("<2f", times)
    doc["accessors"] += [
        {"bufferView": views, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [tmin], "max": [tmax]},
        {"bufferView": views + 1, "componentType": 5126, "count": 2, "type": "VEC3"}]
    doc.setdefault("animations", []).append({
        "name": "truck",
        "samplers": [{"input": acc, "output": acc + 1, "interpolation": "LINEAR"}],
        "channels": [{"sampler": 0, "target": {"node": cam, "path": "translation"}}]})
    doc["asset"]["generator"] = doc["asset"].get("generator", "") + " + bench/temporal_move.py"
    tmp = a.output + ".tmp"
    with open(tmp, "w") as f:
        json.dump(doc, f, separators=(",", ":"))
    os.replace(tmp, a.output)


if __name__ == "__main__":
    main()
