"""The character: an armature and its action <-> core Motion, BVH import onto a new armature, the role map."""
