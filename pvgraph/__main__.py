"""``python -m pvgraph``: the ``pvgraph`` command (:mod:`pvgraph.cli`), for an environment whose
scripts folder is not on the PATH."""

import sys

from pvgraph.cli import main

if __name__ == "__main__":
    sys.exit(main())
