"""Active binocular exploration as episodes (thesis ch. 3): the run (``evaluate``), its records,
report, markdown and video, and its commands.
"""
