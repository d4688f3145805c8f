"""Test-wide setup: the PVG 32 application registers itself as an installed package would.

``pip install .`` declares ``pvgraph.circuits.cli:register`` in the ``pvgraph.circuits`` entry-point
group; a checkout run with ``PYTHONPATH`` has no entry points, so the same registration is
named in ``PVGRAPH_PLUGINS`` (read on the first registry lookup, inherited by subprocesses).
"""

import os

os.environ.setdefault("PVGRAPH_PLUGINS", "pvgraph.circuits.cli:register")
