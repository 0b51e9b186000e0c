"""Sorting as episodes (thesis ch. 5 and 6): the run (``evaluate``), its report, the
accuracy–inspection curve and its score, one measurement on disjoint seed sets, two runs
paired by seed, the videos' overlay and the demo episode.
"""
