"""Sorting policies (random, GP-IPM, SVM-IPM, oracle); filled in by the policies issue."""

__all__: list[str] = []
