"""``ipbench eval perception`` (thesis ch. 5): the classifiers trained and compared on captured
views (``evaluate``), the pool that renders a run's views and trains its models (``prepare``),
its report, the in-hand ablation and fused accuracy against views.
"""
