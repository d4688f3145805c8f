"""Implicit DAE solvers for F(t, y, y') = 0.

``solve_dae`` is pvgraph's own variable-order BDF method in the style of SUNDIALS IDA
(``ida.py``); ``solve_dae_sundials`` runs SUNDIALS IDA itself through scikit-sundae with the
same signature and result type, for cross-checking. For systems whose residual is compiled C,
``cstep`` takes the BDF steps in C with the Python step's numbers. ``testset`` holds index-1
problems of the Bari IVP Test Set with reference solutions.
"""

from pvgraph.solver.events import Event
from pvgraph.solver.result import DAEResult, DenseOutput, EventRecord
from pvgraph.solver.solve import solve_dae
from pvgraph.solver.sundials import solve_dae_sundials

__all__ = ["solve_dae", "solve_dae_sundials", "DAEResult", "Event", "EventRecord",
           "DenseOutput"]
