"""Helpers shared by the tests and the benchmarks (tools/benchmarks): real-mocap paths, synthetic
library clips, and the straightforward reference of the jump search. Never imported by reactive_anim."""
