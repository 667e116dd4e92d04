"""Cycles baseline for Obscura's `--environment`: a glTF scene lit only by a lat-long environment.

    blender -b --factory-startup -P bench/cycles/render_env.py -- \
        --scene S.gltf --environment E.exr [--rotation DEG] [--strength S] \
        --res WxH --spp N --threads 2 --out out.exr [--seed 0]

Blender 3.4 (Debian 12's package). What it sets up, and why:

- The scene is imported by the stock glTF importer (glTF +Y up -> Blender +Z up, i.e.
  Blender (x, y, z) = glTF (x, -z, y)). Imported punctual lights are deleted and emission is
  dropped (Obscura ignores both), so the environment is the only light.
- The camera is the glTF's first perspective camera: lowest index in the file's `cameras[]`,
  ties by the order the importer creates the nodes (Obscura's default `--camera`). None: exit 1.
  The importer gives it the glTF yfov as a vertical field of view (sensor fit VERTICAL, so the
  horizontal one follows --res, as in Obscura) and `znear` as clip start (Cycles clips at that
  *depth*, Obscura starts rays at that distance *along the ray*).
- Every material becomes a pure Diffuse BSDF (Lambert, roughness 0) whose colour is the
  importer's own base-colour graph (baseColorFactor x baseColorTexture, sRGB-decoded, with the
  importer's UV/sampler handling) minus vertex colours (Obscura ignores COLOR_0). Primitives
  without a material get glTF's default material: white. Alpha is ignored.
- World: Texture Coordinate (Generated) -> Mapping (Point, Z rotation = -DEG) -> Environment
  Texture (equirectangular, Closest, Linear, RGB channel-packed so alpha never touches colour)
  -> Background (strength S). docs/environment.md derives the lookup
  (bench/cycles/verify_mapping.py verifies it): in glTF coordinates, for direction d,
      u = 0.5 + atan2(d.z, d.x) / (2 pi) + DEG / 360   (left column = 0)
      v = 0.5 - asin(d.y) / pi                           (top row = 0, OIIO's row 0)
  i.e. the environment turned DEG degrees counter-clockwise about +Y seen from above.
- Cycles, CPU, `threads` fixed, N samples, no adaptive sampling, no denoising, bounces: diffuse
  12, glossy/transmission/volume/transparent 0 (total 12), no clamping, light threshold 0, box
  filter 1 px wide, opaque film, view transform Standard; written as a 32-bit float linear RGB
  EXR (Blender writes scene-linear to EXR whatever the view transform).

Prints `blender_startup_seconds` (process start -> this script), `import_seconds` (glTF import),
`render_seconds` (bpy.ops.render.render only), `write_seconds` and `mean_rgb: r g b` (mean of
the written linear RGB).
"""
import argparse
import math
import os
import sys
import time

import bpy

SCRIPT_START = time.perf_counter()


def process_age_seconds():
    """Seconds since this Blender process started (Linux /proc), or nan."""
    try:
        with open("/proc/self/stat") as f:
            start_ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return uptime - start_ticks / os.sysconf("SC_CLK_TCK")
    except Exception:  # not Linux
        return float("nan")


def fail(msg):
    print(f"error: {msg}", file=sys.stderr, flush=True)
    sys.stdout.flush()
    os._exit(1)  # SystemExit inside a -P script would not set Blender's exit status


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="render_env.py")
    p.add_argument("--scene", required=True)
    p.add_argument("--environment", required=True)
    p.add_argument("--rotation", type=float, default=0.0,
                   help="degrees, counter-clockwise about up (glTF +Y) seen from above")
    p.add_argument("--strength", type=float, default=1.0)
    p.add_argument("--res", default="960x540")
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True)
    try:
        a = p.parse_args(argv)
    except SystemExit as e:
        os._exit(e.code if isinstance(e.code, int) else 2)
    try:
        w, h = (int(x) for x in a.res.lower().split("x"))
        assert w > 0 and h > 0
    except Exception:
        fail(f"--res: expected WxH, got '{a.res}'")
    a.width, a.height = w, h
    for f in (a.scene, a.environment):
        if not os.path.isfile(f):
            fail(f"no such file: {f}")
    if a.spp < 1 or a.threads < 1:
        fail("--spp and --threads must be >= 1")
    return a


def import_gltf(path):
    """Stock importer; returns [(camera index, creation order, object, is perspective)]."""
    import numpy as np
    if "bool" not in np.__dict__:
        # Debian 12's Blender 3.4.1 importer uses np.bool (gltf2_blender_mesh.py, set_poly_smoothing),
        # an alias of the builtin bool that NumPy 1.24 (Debian 12's) removed: the import fails
        # with AttributeError on any mesh. Restoring the alias changes nothing else.
        np.bool = bool
    from io_scene_gltf2.blender.imp import gltf2_blender_node as gnode

    cams = []
    original = gnode.BlenderNode.create_object

    def create_object(gltf, vnode_id):
        obj = original(gltf, vnode_id)
        vnode = gltf.vnodes[vnode_id]
        if vnode.camera_node_idx is not None:
            ci = gltf.data.nodes[vnode.camera_node_idx].camera
            cams.append((ci, len(cams), obj, gltf.data.cameras[ci].type != "orthographic"))
        return obj

    gnode.BlenderNode.create_object = staticmethod(create_object)
    try:
        res = bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
    finally:
        gnode.BlenderNode.create_object = staticmethod(original)
    if "FINISHED" not in res:
        fail(f"glTF import of {path} failed: {res}")
    return cams


def diffuse_everything():
    """Replace every material's surface by a Diffuse BSDF fed by its base colour."""
    default = bpy.data.materials.new("gltf_default_material")
    default.use_nodes = True
    default.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (1, 1, 1, 1)

    for obj in bpy.data.objects:
        if obj.type != "MESH":
            continue
        if len(obj.material_slots) == 0:
            obj.data.materials.append(default)
        for slot in obj.material_slots:
            if slot.material is None:
                slot.material = default

    used = {s.material for o in bpy.data.objects if o.type == "MESH" for s in o.material_slots}
    for mat in used:
        mat.use_nodes = True
        nt = mat.node_tree
        # Vertex colours: Obscura ignores COLOR_0, so the importer's multiply by them becomes x 1.
        for node in list(nt.nodes):
            if node.bl_idname in ("ShaderNodeVertexColor", "ShaderNodeAttribute"):
                for out in node.outputs:
                    for link in list(out.links):
                        to = link.to_socket
                        nt.links.remove(link)
                        if to.type == "RGBA":
                            to.default_value = (1, 1, 1, 1)
                        elif to.type == "VALUE":
                            to.default_value = 1.0
        src_socket, colour = None, (1, 1, 1, 1)
        feeder = next((n for n in nt.nodes if "Base Color" in n.inputs), None)
        if feeder is None:  # e.g. KHR_materials_unlit: emission colour
            feeder = next((n for n in nt.nodes if n.bl_idname in ("ShaderNodeEmission", "ShaderNodeBackground")), None)
            key = "Color"
        else:
            key = "Base Color"
        if feeder is None:
            print(f"warning: material '{mat.name}': no base colour found, using white", flush=True)
        else:
            sock = feeder.inputs[key]
            if sock.is_linked:
                src_socket = sock.links[0].from_socket
                print(f"material '{mat.name}': diffuse colour from node '{src_socket.node.name}'", flush=True)
            else:
                colour = tuple(sock.default_value)
                print(f"material '{mat.name}': diffuse colour {tuple(round(c, 4) for c in colour[:3])}", flush=True)
        diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Roughness"].default_value = 0.0
        diffuse.inputs["Color"].default_value = colour
        if src_socket is not None:
            nt.links.new(src_socket, diffuse.inputs["Color"])
        outputs = [n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
        if not outputs:
            outputs = [nt.nodes.new("ShaderNodeOutputMaterial")]
        for out in outputs:
            for name in ("Volume", "Displacement"):
                for link in list(out.inputs[name].links):
                    nt.links.remove(link)
            nt.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
            out.target = "ALL"
        for n in [n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]:
            nt.nodes.remove(n)


def setup_world(scene, env_path, rotation_deg, strength):
    world = bpy.data.worlds.new("Environment")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.vector_type = "POINT"
    # Point mapping rotates the lookup vector: Z = -DEG turns the environment by +DEG (verified).
    mp.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(-rotation_deg))
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    img = bpy.data.images.load(os.path.abspath(env_path))
    img.colorspace_settings.name = "Linear"
    img.alpha_mode = "CHANNEL_PACKED"
    env.image = img
    env.interpolation = "Closest"
    env.projection = "EQUIRECTANGULAR"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = strength
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    return img


def setup_render(scene, a):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = a.spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = a.seed
    c.use_animated_seed = False
    c.max_bounces = 12
    c.diffuse_bounces = 12
    c.glossy_bounces = 0
    c.transmission_bounces = 0
    c.volume_bounces = 0
    c.transparent_max_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = False
    c.caustics_refractive = False
    c.filter_type = "BOX"
    c.filter_width = 1.0
    c.film_exposure = 1.0
    r = scene.render
    r.threads_mode = "FIXED"
    r.threads = a.threads
    r.resolution_x, r.resolution_y = a.width, a.height
    r.resolution_percentage = 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = False
    r.film_transparent = False
    r.use_motion_blur = False
    r.use_compositing = False
    r.use_sequencer = False
    r.dither_intensity = 0.0
    vs = scene.view_settings
    scene.display_settings.display_device = "sRGB"
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    vs.use_curve_mapping = False
    im = r.image_settings
    im.file_format = "OPEN_EXR"
    im.color_mode = "RGB"
    im.color_depth = "32"
    im.exr_codec = "ZIP"


def exr_string_attributes(path):
    """The string attributes of an OpenEXR file's (first) header."""
    import struct
    attrs = {}
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    pos = 8  # magic + version
    while pos < len(data) and data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack_from("<i", data, type_end + 1)
        value = data[type_end + 5: type_end + 5 + size]
        if data[name_end + 1: type_end] == b"string":
            attrs[data[pos:name_end].decode()] = value.decode(errors="replace")
        pos = type_end + 5 + size
    return attrs


def mmss_seconds(s):
    """Cycles' "MM:SS.cc" (or "HH:MM:SS.cc") -> seconds."""
    t = 0.0
    for part in s.split(":"):
        t = 60.0 * t + float(part)
    return t


def mean_rgb(path):
    import numpy as np
    img = bpy.data.images.load(os.path.abspath(path), check_existing=False)
    img.colorspace_settings.name = "Linear"
    px = np.empty(img.size[0] * img.size[1] * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(-1, 4)[:, :3].astype(np.float64).mean(axis=0)


def main():
    startup = process_age_seconds()
    a = parse_args()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    t0 = time.perf_counter()
    cams = import_gltf(a.scene)
    import_seconds = time.perf_counter() - t0

    persp = sorted((c for c in cams if c[3]), key=lambda c: (c[0], c[1]))
    if not persp:
        fail(f"{a.scene}: no perspective camera (the baseline renders through the glTF's first camera)")
    cam = persp[0][2]
    scene.camera = cam
    lights = [o for o in bpy.data.objects if o.type == "LIGHT"]
    for o in lights:
        bpy.data.objects.remove(o, do_unlink=True)

    diffuse_everything()
    setup_world(scene, a.environment, a.rotation, a.strength)
    setup_render(scene, a)
    bpy.context.view_layer.update()
    d = cam.matrix_world.to_3x3() @ __import__("mathutils").Vector((0, 0, -1))
    print(f"camera: '{cam.name}' (glTF cameras[{persp[0][0]}]), position (Blender) "
          f"{tuple(round(x, 4) for x in cam.matrix_world.translation)}, view direction (glTF) "
          f"{(round(d.x, 4), round(d.z, 4), round(-d.y, 4))}, vertical fov "
          f"{math.degrees(cam.data.angle_y):.3f} deg, clip_start {cam.data.clip_start:g}", flush=True)
    if lights:
        print(f"deleted {len(lights)} imported light(s): the environment is the only light", flush=True)
    setup_seconds = time.perf_counter() - t0 - import_seconds

    t1 = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    render_seconds = time.perf_counter() - t1

    t2 = time.perf_counter()
    out = os.path.abspath(a.out)
    bpy.data.images["Render Result"].save_render(out, scene=scene)
    write_seconds = time.perf_counter() - t2

    m = mean_rgb(out)
    print(f"blender_startup_seconds: {startup:.3f}")
    print(f"import_seconds: {import_seconds:.3f}")
    print(f"setup_seconds: {setup_seconds:.3f}")
    print(f"render_seconds: {render_seconds:.3f}")
    # Cycles' own split of render_seconds, from the metadata it writes into the EXR header
    # (resolution 0.01 s): synchronization = scene sync, BVH, the world's importance map, ...;
    # render = path tracing.
    meta = exr_string_attributes(out)
    for key in ("synchronization_time", "render_time"):
        v = meta.get(f"cycles.ViewLayer.{key}")
        if v is not None:
            print(f"cycles_{key}_seconds: {mmss_seconds(v):.2f}")
    print(f"write_seconds: {write_seconds:.3f}")
    print(f"mean_rgb: {m[0]:.6f} {m[1]:.6f} {m[2]:.6f}", flush=True)


try:
    main()
except Exception:  # an uncaught exception in a -P script leaves Blender's exit status 0
    import traceback
    traceback.print_exc()
    fail("render_env.py failed (traceback above)")
