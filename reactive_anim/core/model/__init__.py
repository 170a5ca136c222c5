"""The shared model every stage uses: skeleton and motion, quaternions, joint roles, BVH, impact,
reaction classes, errors."""
