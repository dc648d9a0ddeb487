# Renders an exported glTF with Blender (Cycles, CPU) under a lat-long environment map, from +Z
# through an orthographic camera 2.4 units tall: lightstage's own view of the material on a plane
# (relight/material/shape_render.h), so the two renders can be compared pixel for pixel.
#   blender -b --factory-startup --python-exit-code 1 --python blender_render_gltf.py -- \
#     IN.gltf ENV.exr OUT.exr SAMPLES RESOLUTION
# Two things Blender 3.4 needs that are not the glTF's doing:
#  * Debian 12's numpy 1.24 dropped np.bool, which the bundled glTF importer still uses.
#  * The importer keeps only KHR_materials_specular's specularColorFactor (as Principled
#    Specular = F0 / 0.08): the extension's specularTexture (the strength w, alpha channel) is
#    stored for export and not rendered. This script connects it as the extension defines it,
#    Principled Specular = w * F0 / 0.08, no specular tint.
import math
import sys

import bpy
import numpy

if 'bool' not in numpy.__dict__:
    numpy.bool = bool
argv = sys.argv[sys.argv.index('--') + 1:]
gltf, env, out, samples, resolution = argv[0], argv[1], argv[2], int(argv[3]), int(argv[4])

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
bpy.ops.import_scene.gltf(filepath=gltf)

import json
with open(gltf) as f:
    asset = json.load(f)
spec = asset['materials'][0].get('extensions', {}).get('KHR_materials_specular')
for material in bpy.data.materials:
    if not material.use_nodes or spec is None:
        continue
    nodes, links = material.node_tree.nodes, material.node_tree.links
    bsdf = next(n for n in nodes if n.bl_idname == 'ShaderNodeBsdfPrincipled')
    for link in list(bsdf.inputs['Specular Tint'].links):
        links.remove(link)
    bsdf.inputs['Specular Tint'].default_value = 0.0
    f0 = min(0.04 * spec['specularColorFactor'][0], 1.0)
    image_uri = asset['images'][asset['textures'][spec['specularTexture']['index']]['source']]['uri']
    import os
    texture = nodes.new('ShaderNodeTexImage')
    texture.image = bpy.data.images.load(os.path.join(os.path.dirname(gltf), image_uri))
    texture.image.colorspace_settings.name = 'Non-Color'
    uv = nodes.new('ShaderNodeUVMap')
    links.new(uv.outputs['UV'], texture.inputs['Vector'])
    scale = nodes.new('ShaderNodeMath')
    scale.operation = 'MULTIPLY'
    scale.inputs[1].default_value = spec.get('specularFactor', 1.0) * f0 / 0.08
    links.new(texture.outputs['Alpha'], scale.inputs[0])
    for link in list(bsdf.inputs['Specular'].links):
        links.remove(link)
    links.new(scale.outputs['Value'], bsdf.inputs['Specular'])

# glTF's +Y up becomes Blender's +Z: glTF (x, y, z) is Blender (x, -z, y). The camera at glTF
# (0, 0, 3) looking down glTF -Z.
camera_data = bpy.data.cameras.new('camera')
camera_data.type = 'ORTHO'
camera_data.ortho_scale = 2.4
camera = bpy.data.objects.new('camera', camera_data)
camera.location = (0.0, -3.0, 0.0)
camera.rotation_euler = (math.radians(90.0), 0.0, 0.0)
scene.collection.objects.link(camera)
scene.camera = camera

# The map: lightstage's lat-long has its centre toward stage -Z (Blender +Y) and u = 0.75 toward
# +X; Blender's has its centre toward -X and u = 0.75 toward +Y: a quarter turn about Z (of the
# lookup direction, so -90 degrees; checked: the other turns differ from lightstage's render 3x).
world = bpy.data.worlds.new('world')
scene.world = world
world.use_nodes = True
tree = world.node_tree
environment = tree.nodes.new('ShaderNodeTexEnvironment')
environment.image = bpy.data.images.load(env)
coordinates = tree.nodes.new('ShaderNodeTexCoord')
mapping = tree.nodes.new('ShaderNodeMapping')
mapping.inputs['Rotation'].default_value = (0.0, 0.0, math.radians(-90.0))
tree.links.new(coordinates.outputs['Generated'], mapping.inputs['Vector'])
tree.links.new(mapping.outputs['Vector'], environment.inputs['Vector'])
tree.links.new(environment.outputs['Color'], tree.nodes['Background'].inputs['Color'])

scene.render.engine = 'CYCLES'
scene.cycles.device = 'CPU'
scene.cycles.samples = samples
scene.cycles.use_adaptive_sampling = False
scene.cycles.use_denoising = False
scene.cycles.seed = 0
scene.cycles.max_bounces = 0  # Direct light only, as lightstage renders (no interreflection).
scene.render.resolution_x = scene.render.resolution_y = resolution
scene.render.resolution_percentage = 100
scene.view_settings.view_transform = 'Standard'
scene.render.image_settings.file_format = 'OPEN_EXR'
scene.render.image_settings.color_depth = '32'
scene.render.image_settings.color_mode = 'RGBA'
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
