"""The Lixel render engine (``bl_idname = "LIXEL"``)."""
