"""The project's tools: the sample-clip generator (`python -m tools.sample_clips`), the benchmarks
(`tools/bench.py`, the package `tools.benchmarks`), environment setup, the test runner and the
extension build. Run them from the repository root."""
