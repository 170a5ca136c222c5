"""What the tests and the benchmarks share, never shipped: where the real mocap lives, the
believability measures, constructed skeletons and poses, reference implementations to check the
core against. Both import it; it imports neither (the import test holds that)."""
