#!/usr/bin/env python3
"""Generate scenes/default.gltf, Obscura's default ambient-occlusion test scene.

The output is a single self-contained glTF 2.0 file: the binary buffer and the
ground texture (a procedurally generated PNG) are embedded as base64 data URIs.

Scene layout (Y up, metres, counter-clockwise front faces):

  * ground         8 x 8 m plane, tiled checker texture, NON-indexed primitive
  * wall_back,     two thin boxes meeting at a right angle behind the scene,
    wall_left      forming creases with each other and with the ground
  * crate          box resting on the ground; one mesh with TWO primitives
                   (reddish body + cream lid that overhangs the body)
  * bowl           thick-walled hemispherical bowl (outer shell, rounded rim,
                   inner shell) with smooth per-vertex normals: a cavity
  * colonnade      parent node with its own transform, holding three nodes
                   that instance ONE 24-sided column mesh with different
                   translation / rotation / scale (one column lies on its side)
  * camera_main    perspective camera "main", elevated 3/4 view
  * camera_top     perspective camera "top", looking straight down

Index types: the bowl uses UNSIGNED_INT, the boxes and the column use
UNSIGNED_SHORT, the ground has no indices at all.

Only the Python standard library is used and the output is deterministic:
running the script twice produces a byte-identical file.

Usage:  python3 scenes/make_default_scene.py [output.gltf]
"""

import base64
import json
import math
import os
import struct
import sys
import zlib

# glTF enums -----------------------------------------------------------------
UNSIGNED_SHORT = 5123
UNSIGNED_INT = 5125
FLOAT = 5126
ARRAY_BUFFER = 34962
ELEMENT_ARRAY_BUFFER = 34963
LINEAR = 9729
LINEAR_MIPMAP_LINEAR = 9987
REPEAT = 10497

NUM_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
COMPONENT_FORMAT = {UNSIGNED_SHORT: "H", UNSIGNED_INT: "I", FLOAT: "f"}


# Small numeric helpers ------------------------------------------------------
def f32(x):
    """Round a Python float to the nearest float32 value."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def f32_json(x):
    """Shortest decimal that parses back to exactly the same float32.

    Used for accessor min/max so that the JSON bounds match the binary data
    bit for bit, without printing 17 digits of float32 rounding noise.
    """
    x = f32(x)
    for digits in range(1, 18):
        candidate = float("%.*g" % (digits, x))
        if f32(candidate) == x:
            return candidate + 0.0  # normalise -0.0 to 0.0
    return x


def tidy(x):
    """Round a transform/camera parameter for readable JSON output."""
    v = round(x, 7)
    return v + 0.0  # avoid "-0.0"


def normalize(v):
    length = math.sqrt(sum(c * c for c in v))
    return tuple(c / length for c in v)


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0])


def quat_axis_angle(axis, degrees):
    """Quaternion (x, y, z, w) for a rotation of `degrees` about `axis`."""
    ax = normalize(axis)
    half = math.radians(degrees) * 0.5
    s = math.sin(half)
    return (ax[0] * s, ax[1] * s, ax[2] * s, math.cos(half))


def quat_mul(a, b):
    """Hamilton product a*b (apply b first, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def quat_from_basis(x, y, z):
    """Quaternion for the rotation matrix whose columns are x, y, z."""
    m00, m10, m20 = x
    m01, m11, m21 = y
    m02, m12, m22 = z
    trace = m00 + m11 + m22
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = ((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = (0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s)
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s)
    if q[3] < 0.0:  # canonical sign: w >= 0
        q = tuple(-c for c in q)
    return normalize(q)


def look_at_quat(eye, target, up=(0.0, 1.0, 0.0)):
    """Rotation that makes a glTF camera at `eye` look at `target`.

    glTF cameras look down their local -Z axis with +Y up, so the local +Z
    axis must point from the target back towards the eye.
    """
    z = normalize(sub(eye, target))
    x = normalize(cross(up, z))
    y = cross(z, x)
    return quat_from_basis(x, y, z)


# Procedural PNG --------------------------------------------------------------
def png_chunk(kind, data):
    """One PNG chunk: length, type, payload, CRC-32 over type + payload."""
    crc = zlib.crc32(kind + data) & 0xFFFFFFFF
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


def make_checker_png(size=64, cells=8):
    """size x size 8-bit RGB checkerboard in two muted colours."""
    light = (158, 150, 132)  # warm sand
    dark = (112, 120, 110)   # sage grey
    cell = size // cells
    rows = []
    for y in range(size):
        row = bytearray([0])  # filter type 0 (None) for every scanline
        for x in range(size):
            row.extend(light if ((x // cell) + (y // cell)) % 2 == 0 else dark)
        rows.append(bytes(row))
    ihdr = struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0)  # 8-bit RGB
    return (b"\x89PNG\r\n\x1a\n"
            + png_chunk(b"IHDR", ihdr)
            + png_chunk(b"IDAT", zlib.compress(b"".join(rows), 9))
            + png_chunk(b"IEND", b""))


# Geometry generators ----------------------------------------------------------
# Each generator returns (positions, normals, indices) with positions/normals
# as lists of 3-tuples and indices as a flat list (counter-clockwise fronts).

def make_box(lo, hi):
    """Axis-aligned box with flat per-face normals (24 vertices, 12 tris)."""
    centre = tuple((a + b) * 0.5 for a, b in zip(lo, hi))
    half = tuple((b - a) * 0.5 for a, b in zip(lo, hi))
    # (normal, u, v) with u x v == normal, so the corner order below is CCW.
    faces = [((1, 0, 0), (0, 0, -1), (0, 1, 0)),
             ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
             ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
             ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
             ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
             ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]
    positions, normals, indices = [], [], []
    for n, u, v in faces:
        base = len(positions)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            positions.append(tuple(centre[i] + half[i] * (n[i] + su * u[i] + sv * v[i])
                                   for i in range(3)))
            normals.append(tuple(float(c) for c in n))
        indices += [base, base + 1, base + 2, base, base + 2, base + 3]
    return positions, normals, indices


def make_column(radius=0.15, height=1.0, sides=24):
    """Capped cylinder standing on y=0, smooth side normals, flat caps."""
    positions, normals, indices = [], [], []
    ring = [(math.cos(2.0 * math.pi * i / sides), math.sin(2.0 * math.pi * i / sides))
            for i in range(sides)]
    ring.append(ring[0])  # duplicate seam vertex so the side is a clean grid

    # Side wall: pairs (bottom, top) for each of the sides+1 ring positions.
    for c, s in ring:
        positions += [(radius * c, 0.0, radius * s), (radius * c, height, radius * s)]
        normals += [(c, 0.0, s), (c, 0.0, s)]
    for i in range(sides):
        b0, t0, b1, t1 = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
        indices += [b0, t0, t1, b0, t1, b1]

    # Caps: a centre vertex plus a ring with the cap's flat normal.
    for y, ny in ((height, 1.0), (0.0, -1.0)):
        centre = len(positions)
        positions.append((0.0, y, 0.0))
        normals.append((0.0, ny, 0.0))
        for c, s in ring[:sides]:
            positions.append((radius * c, y, radius * s))
            normals.append((0.0, ny, 0.0))
        for i in range(sides):
            a = centre + 1 + i
            b = centre + 1 + (i + 1) % sides
            indices += [centre, b, a] if ny > 0.0 else [centre, a, b]
    return positions, normals, indices


def make_bowl(outer=0.55, inner=0.48, shell_segments=32, rim_segments=8,
              slices=64):
    """Thick-walled hemispherical bowl, opening upwards, centred at y=0.

    Built as a surface of revolution of one profile curve that runs
    outer bottom pole -> outer equator -> over a semicircular rim ->
    inner equator -> inner bottom pole.  Each profile point carries its own
    2D normal (radial, y), so the revolved mesh has smooth normals that
    point out of the solid everywhere (into the cavity on the inner shell).
    """
    profile = []  # (rho, y, n_rho, n_y)
    # Outer shell, angle from -90 deg (bottom) up to 0 deg (equator).
    for k in range(shell_segments + 1):
        a = -0.5 * math.pi * (1.0 - k / shell_segments)
        c, s = math.cos(a), math.sin(a)
        profile.append((outer * c, outer * s, c, s))
    # Rim: a half torus whose tube joins the two shells tangentially.
    mid, tube = 0.5 * (outer + inner), 0.5 * (outer - inner)
    for k in range(1, rim_segments):  # endpoints belong to the shells
        b = math.pi * k / rim_segments
        c, s = math.cos(b), math.sin(b)
        profile.append((mid + tube * c, tube * s, c, s))
    # Inner shell, equator back down to the bottom; normals face the axis/up.
    for k in range(shell_segments + 1):
        a = -0.5 * math.pi * k / shell_segments
        c, s = math.cos(a), math.sin(a)
        profile.append((inner * c, inner * s, -c, -s))
    # Make the two poles exact (cos(-pi/2) is not exactly zero).
    profile[0] = (0.0, -outer, 0.0, -1.0)
    profile[-1] = (0.0, -inner, 0.0, 1.0)

    positions, normals, indices = [], [], []
    for rho, y, nr, ny in profile:
        for j in range(slices + 1):  # slices+1: duplicated seam column
            phi = 2.0 * math.pi * (j % slices) / slices
            c, s = math.cos(phi), math.sin(phi)
            positions.append((rho * c, y, rho * s))
            normals.append((nr * c, ny, nr * s))

    last = len(profile) - 1
    row = slices + 1
    for k in range(last):
        for j in range(slices):
            a = k * row + j            # (k,   j)
            b = (k + 1) * row + j      # (k+1, j)
            c = b + 1                  # (k+1, j+1)
            d = a + 1                  # (k,   j+1)
            # Skip the triangle that would collapse onto a pole.
            if k != last - 1:
                indices += [a, b, c]
            if k != 0:
                indices += [a, c, d]
    return positions, normals, indices


def make_ground(half=4.0, tiles=4.0):
    """Two-triangle ground plane at y=0, non-indexed, UVs tiling `tiles` times."""
    corners = {  # corner -> (x, z, u, v); v runs towards -Z
        "nw": (-half, -half, 0.0, tiles), "ne": (half, -half, tiles, tiles),
        "sw": (-half, half, 0.0, 0.0), "se": (half, half, tiles, 0.0),
    }
    order = ["sw", "se", "ne", "sw", "ne", "nw"]  # CCW seen from above
    positions = [(corners[k][0], 0.0, corners[k][1]) for k in order]
    normals = [(0.0, 1.0, 0.0)] * len(order)
    uvs = [(corners[k][2], corners[k][3]) for k in order]
    return positions, normals, uvs


# glTF assembly -----------------------------------------------------------------
class GltfBuilder:
    """Accumulates one binary buffer plus the JSON arrays that reference it."""

    def __init__(self):
        self.blob = bytearray()
        self.doc = {
            "asset": {"version": "2.0",
                      "generator": "obscura make_default_scene.py"},
            "scene": 0,
            "scenes": [],
            "nodes": [],
            "meshes": [],
            "materials": [],
            "cameras": [],
            "textures": [],
            "images": [],
            "samplers": [],
            "accessors": [],
            "bufferViews": [],
            "buffers": [],
        }

    def _buffer_view(self, data, target):
        """Append `data` at a 4-byte aligned offset; return the view index."""
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        view = {"buffer": 0, "byteOffset": len(self.blob),
                "byteLength": len(data), "target": target}
        self.blob.extend(data)
        self.doc["bufferViews"].append(view)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, values, acc_type, component_type, with_bounds=False):
        """Pack a list of tuples (or scalars) into a new accessor."""
        n = NUM_COMPONENTS[acc_type]
        flat = [c for v in values for c in v] if n > 1 else list(values)
        fmt = "<%d%s" % (len(flat), COMPONENT_FORMAT[component_type])
        data = struct.pack(fmt, *flat)
        target = ELEMENT_ARRAY_BUFFER if acc_type == "SCALAR" else ARRAY_BUFFER
        acc = {"bufferView": self._buffer_view(data, target),
               "componentType": component_type,
               "count": len(flat) // n,
               "type": acc_type}
        if with_bounds:  # bounds of the float32 values actually stored
            acc["min"] = [f32_json(min(v[i] for v in values)) for i in range(n)]
            acc["max"] = [f32_json(max(v[i] for v in values)) for i in range(n)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def primitive(self, material, positions, normals, indices=None,
                  index_type=UNSIGNED_SHORT, uvs=None):
        attributes = {
            "POSITION": self.accessor(positions, "VEC3", FLOAT, with_bounds=True),
            "NORMAL": self.accessor(normals, "VEC3", FLOAT),
        }
        if uvs is not None:
            attributes["TEXCOORD_0"] = self.accessor(uvs, "VEC2", FLOAT)
        prim = {"attributes": attributes, "material": material, "mode": 4}
        if indices is not None:
            if index_type == UNSIGNED_SHORT:
                assert max(indices) < 65535, "too many vertices for u16"
            prim["indices"] = self.accessor(indices, "SCALAR", index_type)
        return prim

    def add(self, key, item):
        self.doc[key].append(item)
        return len(self.doc[key]) - 1

    def material(self, name, rgb, texture=None):
        pbr = {"baseColorFactor": [rgb[0], rgb[1], rgb[2], 1.0],
               "metallicFactor": 0.0,
               "roughnessFactor": 1.0}
        if texture is not None:
            pbr["baseColorTexture"] = {"index": texture, "texCoord": 0}
        return self.add("materials", {"name": name, "pbrMetallicRoughness": pbr})

    def node(self, name, translation=None, rotation=None, scale=None, **extra):
        node = {"name": name}
        if translation is not None:
            node["translation"] = [tidy(c) for c in translation]
        if rotation is not None:
            node["rotation"] = [tidy(c) for c in rotation]
        if scale is not None:
            node["scale"] = [tidy(c) for c in scale]
        node.update(extra)
        return self.add("nodes", node)

    def finish(self):
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        uri = ("data:application/octet-stream;base64,"
               + base64.b64encode(bytes(self.blob)).decode("ascii"))
        self.doc["buffers"].append({"byteLength": len(self.blob), "uri": uri})
        return self.doc


def build_scene():
    g = GltfBuilder()

    # Materials (all diffuse: metallic 0, roughness 1).
    g.add("samplers", {"magFilter": LINEAR, "minFilter": LINEAR_MIPMAP_LINEAR,
                       "wrapS": REPEAT, "wrapT": REPEAT})
    png = make_checker_png()
    g.add("images", {"name": "ground_checker",
                     "uri": "data:image/png;base64,"
                            + base64.b64encode(png).decode("ascii")})
    checker = g.add("textures", {"sampler": 0, "source": 0})
    m_ground = g.material("ground", (1.0, 1.0, 1.0), texture=checker)
    m_wall = g.material("wall", (0.8, 0.8, 0.8))
    m_crate = g.material("crate_body", (0.7, 0.2, 0.15))
    m_lid = g.material("crate_lid", (0.85, 0.75, 0.55))
    m_bowl = g.material("bowl", (0.2, 0.35, 0.75))
    m_stone = g.material("column_stone", (0.88, 0.86, 0.8))

    # Meshes.
    pos, nrm, uv = make_ground()
    mesh_ground = g.add("meshes", {"name": "ground", "primitives": [
        g.primitive(m_ground, pos, nrm, indices=None, uvs=uv)]})

    # Walls: 12 cm thick, 2.4 m tall, geometry centred on the node origin.
    wall_half = 1.2
    mesh_wall_back = g.add("meshes", {"name": "wall_back", "primitives": [
        g.primitive(m_wall, *make_box((-2.81, -wall_half, -0.06),
                                      (2.81, wall_half, 0.06)))]})
    mesh_wall_left = g.add("meshes", {"name": "wall_left", "primitives": [
        g.primitive(m_wall, *make_box((-0.06, -wall_half, -2.1),
                                      (0.06, wall_half, 2.1)))]})

    # Crate: body 0.8 x 0.6 x 0.8 standing on y=0, lid overhanging by 5 cm.
    mesh_crate = g.add("meshes", {"name": "crate", "primitives": [
        g.primitive(m_crate, *make_box((-0.4, 0.0, -0.4), (0.4, 0.6, 0.4))),
        g.primitive(m_lid, *make_box((-0.45, 0.6, -0.45), (0.45, 0.68, 0.45))),
    ]})

    bowl_outer = 0.55
    mesh_bowl = g.add("meshes", {"name": "bowl", "primitives": [
        g.primitive(m_bowl, *make_bowl(outer=bowl_outer),
                    index_type=UNSIGNED_INT)]})

    mesh_column = g.add("meshes", {"name": "column", "primitives": [
        g.primitive(m_stone, *make_column())]})

    # Cameras.
    aspect = 16.0 / 9.0
    cam_main = g.add("cameras", {"name": "main", "type": "perspective",
                                 "perspective": {"yfov": 0.7,
                                                 "aspectRatio": aspect,
                                                 "znear": 0.05, "zfar": 100.0}})
    cam_top = g.add("cameras", {"name": "top", "type": "perspective",
                                "perspective": {"yfov": 0.9,
                                                "aspectRatio": aspect,
                                                "znear": 0.05, "zfar": 100.0}})

    # Nodes.
    up_y = (0.0, 1.0, 0.0)
    roots = [
        g.node("ground", mesh=mesh_ground),
        g.node("wall_back", translation=(0.19, wall_half, -2.06),
               mesh=mesh_wall_back),
        g.node("wall_left", translation=(-2.56, wall_half, 0.1),
               mesh=mesh_wall_left),
        g.node("crate", translation=(-1.2, 0.0, -1.1),
               rotation=quat_axis_angle(up_y, 25.0), mesh=mesh_crate),
        # The bowl's outer pole touches the ground at the node origin - R.
        g.node("bowl", translation=(-0.9, bowl_outer, 0.9), mesh=mesh_bowl),
    ]

    # Colonnade: one column mesh instanced three times below a parent with
    # its own rotation + translation, so the hierarchy must be composed.
    columns = [
        g.node("column_tall", scale=(1.0, 2.2, 1.0), mesh=mesh_column),
        g.node("column_short", translation=(0.8, 0.0, 0.0),
               rotation=quat_axis_angle(up_y, 7.5), scale=(1.2, 1.2, 1.2),
               mesh=mesh_column),
        # Lying on its side: rotate 90 deg about Z (local +Y -> -X), then 20
        # deg about Y; lifted by its scaled radius (0.9 * 0.15) to touch y=0.
        g.node("column_fallen", translation=(0.9, 0.9 * 0.15, 1.0),
               rotation=quat_mul(quat_axis_angle(up_y, 20.0),
                                 quat_axis_angle((0.0, 0.0, 1.0), 90.0)),
               scale=(0.9, 0.9, 0.9), mesh=mesh_column),
    ]
    roots.append(g.node("colonnade", translation=(1.2, 0.0, -0.8),
                        rotation=quat_axis_angle(up_y, 30.0),
                        children=columns))

    # Main camera: elevated 3/4 view of the scene centre.
    eye, target = (4.6, 3.6, 5.2), (-0.2, 0.5, -0.4)
    roots.append(g.node("camera_main", translation=eye,
                        rotation=look_at_quat(eye, target), camera=cam_main))
    # Top camera: 10 m above the origin looking straight down (-90 deg about
    # X maps the camera's -Z onto world -Y; image "up" is world -Z).
    roots.append(g.node("camera_top", translation=(0.0, 10.0, 0.0),
                        rotation=quat_axis_angle((1.0, 0.0, 0.0), -90.0),
                        camera=cam_top))

    g.doc["scenes"].append({"name": "default", "nodes": roots})
    return g.finish()


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "default.gltf")
    doc = build_scene()
    text = json.dumps(doc, indent=1) + "\n"
    with open(out, "w", encoding="ascii", newline="\n") as f:
        f.write(text)
    triangles = 0
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            acc = prim.get("indices", prim["attributes"]["POSITION"])
            triangles += doc["accessors"][acc]["count"] // 3
    print("wrote %s (%d bytes, %d meshes, %d nodes, %d triangles in meshes)"
          % (out, len(text), len(doc["meshes"]), len(doc["nodes"]), triangles))


if __name__ == "__main__":
    main()
