"""Data captured with the simulator: the training and test views perception learns from
(``dataset``), in-hand views and the factors an ablation removes from them, the exploration
recognition database, and the README's pictures of an env id's objects and sensor
(``figures``). Perception itself never imports the simulator; these rigs render what it
learns from.
"""
