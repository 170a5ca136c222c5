"""The bake: reading the scene, the worker thread, writing the new action, preview, and the bundled inputs."""
