"""The demo, the README's main command (`bash tools/run_demo.sh`, or `python -m tools.demo` with the bpy
environment): the sample walk hit four times, baked by the add-on's own operators, saved as
out/demo.blend and rendered as out/demo_filmstrip.png.

    scene.py    a fresh Blender: the walk imported onto an armature, a capsule mannequin, floor, camera, sun
    markers.py  the four impacts, aimed from the character's facing at their frames, with arrows
    render.py   the filmstrip: frames around each impact rendered headless, composed into one PNG
    __main__.py the steps in order, with timings
"""
