"""The gpu pipeline: GPU context, batches, depth pass, shading pass, read-back.
Imports bpy and gpu; the entry point is :func:`.pipeline.render_shadows`."""
