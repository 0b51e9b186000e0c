"""Benchmark entry points: the ``ipbench`` command, the demo episode and the benchmarks."""

__all__: list[str] = []
