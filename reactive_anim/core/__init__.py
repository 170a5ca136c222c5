"""The pure core: numpy, MuJoCo and onnxruntime only. Never imports bpy (see README.md here)."""
