# Run by tests/test_blender.cpp inside Blender, headless:
#   blender -b --factory-startup -P composite_passes.py -- IN.exr OUTDIR WxH PASS...
# Loads IN.exr as Blender's compositor does (an Image node on a multilayer
# image), writes the names and types of the node's outputs to
# OUTDIR/outputs.txt, then for each PASS links that output to the Composite
# node and renders (the tree has no Render Layers node, so only the
# compositor runs) into OUTDIR/PASS.exr, 32-bit float: what a compositor
# artist gets from the pass.
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
src, out_dir, passes = args[0], args[1], args[3:]
# The frame size: a multilayer image reports 0 x 0 until a pass is read.
width, height = (int(v) for v in args[2].split("x"))

image = bpy.data.images.load(src)
image.size[:]  # reading it loads the file, so the Image node below gets one output per pass
scene = bpy.context.scene
scene.use_nodes = True
tree = scene.node_tree
for node in list(tree.nodes):
    tree.nodes.remove(node)
reader = tree.nodes.new("CompositorNodeImage")
reader.image = image
composite = tree.nodes.new("CompositorNodeComposite")

with open(out_dir + "/outputs.txt", "w") as f:
    for socket in reader.outputs:
        if socket.enabled:
            f.write("%s %s\n" % (socket.name, socket.type))

settings = scene.render
settings.resolution_x, settings.resolution_y = width, height
settings.resolution_percentage = 100
settings.image_settings.file_format = "OPEN_EXR"
settings.image_settings.color_depth = "32"
for name in passes:
    tree.links.new(reader.outputs[name], composite.inputs[0])
    settings.filepath = out_dir + "/" + name + ".exr"
    bpy.ops.render.render(write_still=True)
