"""``ipbench bench``: speed figures printed, never asserted — the simulated cell (``sim``), sorting
episodes (``episodes``), exploration and perception.
"""
