"""Reproducibility: stage digests of the pipeline for fixed inputs and ``ipbench check``, which
compares them (and an episode battery) with the recorded reference.
"""
