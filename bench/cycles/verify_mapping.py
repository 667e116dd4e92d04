"""Verify how Blender/Cycles maps an equirectangular EXR onto directions.

    blender -b --factory-startup -P bench/cycles/verify_mapping.py -- [--workdir DIR] [--width 65 --height 33]

What it does (Cycles, CPU, emission-only World, no objects):

1. Writes an "index" lat-long EXR with `oiiotool` (OpenImageIO, the library Obscura reads
   environment files with): texel (col, row) holds R = col, G = row, B = 0.5, where row 0 is
   OIIO's first (top) scanline. Odd sizes put the cardinal directions on texel centres.
2. Checks which file row Blender's image loader puts at v = 1 (the top of its bottom-up buffer).
3. Renders the centre pixel of cameras looking along Blender +X, -X, +Y, -Y, +Z, -Z and prints
   the texel each sees.
4. Renders the six faces of a cube map (90 degree perspective cameras, 48x48 pixels, pixel filter
   width 0.01 so each sample goes through the pixel centre) and compares every pixel's texel with
   the formula under test, in glTF coordinates (glTF (x, y, z) = Blender (x, z, -y)):
       u = 0.5 + atan2(d.z, d.x) / (2 pi)      u = 0 at the left column
       v = 0.5 - asin(d.y) / pi                v = 0 at the top row (OIIO row 0)
       col = floor(u * W), row = floor(v * H)
   Pixels whose u or v lies within 1e-3 texel of a texel edge are not counted (either texel is right).
5. Repeats 4 with Texture Coordinate (Generated / Object) -> Mapping (Point / Texture, Z rotation
   +theta / -theta) -> Environment Texture, and compares with the formula for an environment
   rotated by theta counter-clockwise about up seen from above (right-handed about glTF +Y =
   Blender +Z), i.e. a lookup with u' = u + theta / 360 (mod 1).
"""
import argparse
import math
import os
import subprocess
import sys

import bpy
from mathutils import Vector


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--workdir", default="/tmp/obscura_verify_mapping")
    p.add_argument("--width", type=int, default=65)
    p.add_argument("--height", type=int, default=33)
    p.add_argument("--theta", type=float, default=40.0)
    p.add_argument("--face-res", type=int, default=48)
    return p.parse_args(argv)


def write_index_exr(path, w, h):
    """R = column, G = row (row 0 = OIIO's first scanline = top), B = 0.5; float EXR."""
    cmd = ["oiiotool", "--create", f"{w}x{h}", "3"]
    for c in range(w):
        cmd += [f"--fill:color={c},0,0.5", f"1x{h}+{c}+0"]
    cmd += ["--create", f"{w}x{h}", "3"]
    for r in range(h):
        cmd += [f"--fill:color=0,{r},0", f"{w}x1+0+{r}"]
    cmd += ["--add", "-d", "float", "-o", path]
    subprocess.run(cmd, check=True)


def setup_scene(env_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = 1
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.filter_type = "BOX"          # Cycles' filter importance sampling: offsets within +-width/2
    c.filter_width = 0.01
    c.max_bounces = 0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"

    world = bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(env_path)
    env.image.colorspace_settings.name = "Linear"
    env.interpolation = "Closest"
    env.projection = "EQUIRECTANGULAR"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 1.0
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])

    cam_data = bpy.data.cameras.new("Cam")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "AUTO"
    cam_data.angle = math.radians(90.0)
    cam_data.clip_start = 1e-3
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene, world, env, cam


def set_rotation_chain(world, env, coord_output, mapping_type, z_deg):
    nt = world.node_tree
    for n in list(nt.nodes):
        if n.bl_idname in ("ShaderNodeTexCoord", "ShaderNodeMapping"):
            nt.nodes.remove(n)
    if coord_output is None:
        return
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.vector_type = mapping_type
    mp.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(z_deg))
    nt.links.new(tc.outputs[coord_output], mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], env.inputs["Vector"])


def aim(cam, blender_dir):
    d = Vector(blender_dir).normalized()
    up = "Y"
    cam.rotation_mode = "QUATERNION"
    cam.rotation_quaternion = d.to_track_quat("-Z", up)
    cam.location = (0.0, 0.0, 0.0)
    bpy.context.view_layer.update()


def render_pixels(scene, path, res):
    """Render, save EXR, reload it; returns (rows bottom-up) list of (r, g, b) per pixel."""
    scene.render.resolution_x = res
    scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path, check_existing=False)
    img.colorspace_settings.name = "Linear"
    px = list(img.pixels)
    w, h = img.size
    bpy.data.images.remove(img)
    return [[tuple(px[4 * (j * w + i): 4 * (j * w + i) + 3]) for i in range(w)] for j in range(h)]


def pixel_dirs(cam, res):
    """World (Blender) direction of each pixel centre, j = 0 the bottom row (Blender's buffer order)."""
    m = cam.matrix_world.to_3x3()
    t = math.tan(cam.data.angle / 2.0)
    dirs = []
    for j in range(res):
        row = []
        for i in range(res):
            x = (2.0 * (i + 0.5) / res - 1.0) * t
            y = (2.0 * (j + 0.5) / res - 1.0) * t
            row.append((m @ Vector((x, y, -1.0))).normalized())
        dirs.append(row)
    return dirs


def gltf_from_blender(b):
    return (b.x, b.z, -b.y)


def predict(dg, w, h, rot_deg):
    """Texel (col, row) of glTF direction dg under the formula, with the environment rotated."""
    x, y, z = dg
    u = 0.5 + math.atan2(z, x) / (2.0 * math.pi) + rot_deg / 360.0
    u -= math.floor(u)
    v = 0.5 - math.asin(max(-1.0, min(1.0, y))) / math.pi
    fu, fv = u * w, v * h
    near_edge = (abs(fu - round(fu)) < 1e-3) or (abs(fv - round(fv)) < 1e-3)
    return int(math.floor(fu)) % w, min(int(math.floor(fv)), h - 1), near_edge


FACES = {"+X": (1, 0, 0), "-X": (-1, 0, 0), "+Y": (0, 1, 0), "-Y": (0, -1, 0),
         "+Z": (0, 0, 1), "-Z": (0, 0, -1)}


def cube_test(scene, cam, args, rot_degs, tag):
    """Per rotation in rot_degs: pixels (not on texel edges) whose texel does / does not match
    predict(..., rot); returns {rot: (ok, bad, skipped, examples)}."""
    stats = {rot: [0, 0, 0, []] for rot in rot_degs}
    for name, d in FACES.items():
        aim(cam, d)
        path = os.path.join(args.workdir, f"cube_{tag}_{name.replace('+', 'p').replace('-', 'm')}.exr")
        px = render_pixels(scene, path, args.face_res)
        dirs = pixel_dirs(cam, args.face_res)
        for j in range(args.face_res):
            for i in range(args.face_res):
                r, g, _ = px[j][i]
                got = (int(round(r)), int(round(g)))
                for rot, st in stats.items():
                    col, row, edge = predict(gltf_from_blender(dirs[j][i]), args.width, args.height, rot)
                    if edge:
                        st[2] += 1
                    elif got == (col, row):
                        st[0] += 1
                    else:
                        st[1] += 1
                        if len(st[3]) < 3:
                            st[3].append((name, i, j, got, (col, row)))
    return {rot: tuple(st) for rot, st in stats.items()}


def main():
    args = parse_args()
    os.makedirs(args.workdir, exist_ok=True)
    env_path = os.path.join(args.workdir, f"index_{args.width}x{args.height}.exr")
    write_index_exr(env_path, args.width, args.height)
    print(f"[verify] wrote {env_path} with oiiotool (R = column, G = row, row 0 = OIIO top row)")

    scene, world, env, cam = setup_scene(env_path)

    # 2. Which file row does Blender put at the top (v = 1, last row of its bottom-up buffer)?
    img = env.image
    w, h = img.size
    px = list(img.pixels)
    top_g = px[4 * ((h - 1) * w + 0) + 1]
    bottom_g = px[4 * 0 + 1]
    left_r, right_r = px[0], px[4 * (w - 1)]
    print(f"[verify] Blender buffer: last row (v=1) has G={top_g:g}, first row (v=0) has G={bottom_g:g}; "
          f"first column R={left_r:g}, last column R={right_r:g}")
    print("[verify] => OIIO row 0 (top) is Blender's v = 1 (top): "
          f"{'YES' if top_g == 0 and bottom_g == h - 1 else 'NO'}")

    # 3. Cardinal directions, centre pixel of a 1x1 render.
    cam.data.angle = math.radians(1.0)
    print("[verify] cardinal directions (centre pixel; glTF direction, texel seen, formula):")
    for name, d in FACES.items():
        aim(cam, d)
        p = render_pixels(scene, os.path.join(args.workdir, "cardinal.exr"), 1)[0][0]
        dg = gltf_from_blender(Vector(d))
        col, row, edge = predict(dg, args.width, args.height, 0.0)
        u = (p[0] + 0.5) / args.width
        v = (p[1] + 0.5) / args.height
        print(f"[verify]   Blender {name} = glTF {tuple(int(c) for c in dg)}: texel col={p[0]:g} row={p[1]:g} "
              f"(u~{u:.3f}, v_top~{v:.3f}); formula col={col} row={row}{' (edge)' if edge else ''}")
    cam.data.angle = math.radians(90.0)

    # 4. Dense cube-map test of the formula.
    ok, bad, skipped, ex = cube_test(scene, cam, args, [0.0], "norot")[0.0]
    print(f"[verify] formula, no Vector input: {ok} match, {bad} mismatch, {skipped} on texel edges {ex}")

    # 5. Rotation: which Mapping setup rotates the environment by +theta (CCW from above)?
    th = args.theta
    for coord in ("Generated", "Object"):
        set_rotation_chain(world, env, coord, "POINT", 0.0)
        ok, bad, skipped, ex = cube_test(scene, cam, args, [0.0], f"{coord}_id")[0.0]
        print(f"[verify] TexCoord {coord} -> Mapping identity: {ok} match, {bad} mismatch, {skipped} edge")
        for mtype in ("POINT", "TEXTURE"):
            for sign in (+1, -1):
                set_rotation_chain(world, env, coord, mtype, sign * th)
                res = cube_test(scene, cam, args, [+th, -th], f"{coord}_{mtype}_{sign}")
                print(f"[verify] TexCoord {coord} -> Mapping {mtype} Z={sign * th:+g} deg: "
                      f"matches env rotated +{th:g} (u'=u+theta/360): {res[+th][0]} ok / {res[+th][1]} bad; "
                      f"rotated -{th:g}: {res[-th][0]} ok / {res[-th][1]} bad")

    # A physical check of the sense: rotate by +90 deg; the texel at glTF +X (image centre column)
    # must move to R_y(+90) (1,0,0) = glTF (0,0,-1) = Blender +Y.
    set_rotation_chain(world, env, "Generated", "POINT", -90.0)
    cam.data.angle = math.radians(1.0)
    aim(cam, (0, 1, 0))
    p = render_pixels(scene, os.path.join(args.workdir, "cardinal.exr"), 1)[0][0]
    col, row, edge = predict((0.0, 0.0, -1.0), args.width, args.height, 90.0)
    print(f"[verify] Point Z=-90: camera along Blender +Y (glTF -Z) sees col={p[0]:g} row={p[1]:g}; "
          f"formula rotated +90 deg: col={col} row={row}{' (edge)' if edge else ''} (u = 0.5, the centre column)")


main()
