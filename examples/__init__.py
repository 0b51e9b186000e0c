"""Examples of evaluating a method of your own with ipbench (``docs/custom.md``).

- :mod:`examples.my_policy`: a sorting policy, run as
  ``ipbench eval sorting --policies random,examples.my_policy:LargestFirst``;
- :mod:`examples.my_classifier`: a classifier, run as
  ``ipbench eval perception --classifiers gp,examples.my_classifier:LogisticClassifier``.

Run the commands from the repository's root folder (or add it to ``PYTHONPATH``), so that
``examples`` can be imported.
"""
