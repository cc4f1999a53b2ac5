# Imports each glb given after "--" into an empty Blender scene with Blender's
# own glTF importer and prints one line per file:
#   RAYSWEEP_OK <file> <mesh objects> <triangles>   or   RAYSWEEP_FAIL <file> <reason>
# Run: blender -b --factory-startup --python blender_import_glb.py -- FILE...
import sys

import numpy

numpy.bool = bool  # Blender 3.4's importer still uses np.bool, gone in numpy 1.24
import bpy  # noqa: E402

for path in sys.argv[sys.argv.index("--") + 1:]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        bpy.ops.import_scene.gltf(filepath=path)
    except Exception as e:  # the importer raises RuntimeError with Python's traceback
        print("RAYSWEEP_FAIL", path, str(e).splitlines()[-1] if str(e) else type(e).__name__, flush=True)
        continue
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    triangles = 0
    for o in meshes:
        o.data.calc_loop_triangles()
        triangles += len(o.data.loop_triangles)
    print("RAYSWEEP_OK", path, len(meshes), triangles, flush=True)
