"""bpy -> plain data: the camera, light and bounds the warp core needs
(:mod:`.describe`) and the triangles the gpu pipeline draws (:mod:`.geometry`).
Imports bpy."""
