"""The Blender layer (bpy, main thread only). See README.md here."""
