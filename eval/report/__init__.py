"""``ipbench report docs``: the documentation's results pages and the README's headline,
generated from results files.
"""
