"""The project's own sample skeleton and clips (sample_clips/), generated from code.

Why this exists: tests, demos and the reaction library need motion that anyone may redistribute
and that can be rebuilt from code, so the clips are procedural, not captured. Run from the
repository root:

    python -m tools.sample_clips                  # writes sample_clips/*.bvh and library.toml
    python -m tools.sample_clips --out DIR        # writes elsewhere
    python -m tools.sample_clips --sheets out/contact_sheets   # also draws contact sheet PNGs

Everything is deterministic (no randomness), so regenerating gives byte-identical files (the
physics falls: on the same MuJoCo build and CPU). Clip families are parameter tables: a walk or
run is a `Gait` (gaits.py), a stepping reaction a `Push` row of STEPS and a sway a row of SWAYS
(steps.py; the balance model of balance.py decides the steps), a fall a `Fall` row of FALLS
(falls.py, physics), a get-up a list of key poses in GETUPS (getups.py). catalogue.py lists every
clip (CLIPS) and writes them; to add one, write a function returning a Motion on
`sample_skeleton()` and list it there.

Modules, each importable on its own (`from tools.sample_clips.skeleton import sample_skeleton`):
skeleton (the skeleton, world axes, directions), curves (interpolators), poses (bodies by named
angles), ik (limb IK), gaits (walk, run), idle, balance (the pendulum balance model), steps
(stepping reactions and sways), falls, getups, catalogue (the clip list, library.toml, writing),
sheets (contact sheet PNGs), __main__ (the command line).

World: metres, Z up; the character faces -Y (Blender's convention), so its left (.L) is +X. In the
written BVH (Y up) it faces +Z.
"""
