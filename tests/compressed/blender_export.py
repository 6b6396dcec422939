"""Blender's glTF exporter as a source of files graftal reads (run inside
`blender -b --python` by compare.py): each `NAME/orig.glb` under the work
folder is imported and exported again as `NAME/blender.glb` (Blender's
defaults), and, where this Blender has its Draco library, as
`NAME/blender-draco.glb` with Draco compression. Prints `DRACO yes|no`."""

import os
import sys

import bpy

try:
    import numpy
except ImportError:
    # Blender's embedded Python takes its prefix from the first python3 on
    # PATH; under pyenv (or a venv) that is not the system one, whose
    # dist-packages hold Debian's python3-numpy.
    sys.path.append("/usr/lib/python3/dist-packages")
    import numpy

# Blender 3.4's glTF importer still says `np.bool`, which numpy 1.24
# (Debian 12's python3-numpy, the one Blender's Python sees) removed.
if "bool" not in numpy.__dict__:
    numpy.bool = bool

work = sys.argv[sys.argv.index("--") + 1]
try:
    from io_scene_gltf2.io.com.gltf2_io_draco_compression_extension import dll_exists

    draco = dll_exists(quiet=True)
except Exception:  # an exporter without the module has no Draco either
    draco = False
print("DRACO", "yes" if draco else "no")
for name in sorted(os.listdir(work)):
    source = os.path.join(work, name, "orig.glb")
    if not os.path.exists(source):
        continue
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=source)
    bpy.ops.export_scene.gltf(filepath=os.path.join(work, name, "blender.glb"), export_format="GLB")
    if draco:
        bpy.ops.export_scene.gltf(
            filepath=os.path.join(work, name, "blender-draco.glb"),
            export_format="GLB",
            export_draco_mesh_compression_enable=True,
        )
