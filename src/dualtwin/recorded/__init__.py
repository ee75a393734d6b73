"""Recorded runs: users' recordings (the paper's logs, CSV/TSV, ROS 2 bags in MCAP) become run folders.

An imported run is a first-class run (``kind: recorded`` in its manifest) that ``compare``, ``analyze`` and
``align --reference`` read like a twin's. Each importer validates everything before writing anything::

    from dualtwin.recorded import import_paper, import_table, import_mcap
    run = import_paper("logs/", suite="suite.json", robot="cartpole", out="runs/real")
"""

from dualtwin.recorded.bag import import_mcap
from dualtwin.recorded.paper import import_paper
from dualtwin.recorded.table import import_table

__all__ = ["import_mcap", "import_paper", "import_table"]
