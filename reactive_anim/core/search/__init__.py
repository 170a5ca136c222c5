"""Search (Eq. 1): the clip and jump frame in the predicted class, over a compiled, cached library."""
