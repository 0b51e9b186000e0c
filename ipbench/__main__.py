"""``python -m ipbench``: the ``ipbench`` command (:func:`ipbench.eval.cli.main`)."""

import sys

from ipbench.eval.cli import main

if __name__ == "__main__":
    sys.exit(main())
