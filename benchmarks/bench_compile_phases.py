"""Where one compile spends its time: process CPU of the compiler's stages.

Wraps the stages of :func:`pvgraph.compiler.compile_circuit` (template tracing, variable
declaration, connection sets, symbol checks, alias elimination, index reduction, code and
Jacobian generation) with timers and compiles one case of ``bench_scaling.py``; the rest of
the total is the per-component loop and the circuit's own checks.

Run: ``python benchmarks/bench_compile_phases.py chain:20000`` (or ``wide:10000``).
"""

from __future__ import annotations

import functools
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))


def main(case: str) -> None:
    import pvgraph._templates as T
    import pvgraph.compiler as C
    import pvgraph.index_reduction as IR
    import pvgraph.system as S
    from bench_scaling import chain, wide
    spent: dict[str, float] = {}

    def wrap(owner, name, label=None):
        fn = getattr(owner, name)

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                key = label or name
                spent[key] = spent.get(key, 0.0) + time.process_time() - t0
        setattr(owner, name, timed)
    for name in ("_eliminate_aliases", "_connection_equations", "_declare_variables",
                 "_check_symbols", "template_roles"):
        wrap(C, name)
    wrap(IR, "reduce_index")
    wrap(S, "build_system")
    wrap(T.Templates, "trace", "template tracing")
    kind, size = case.split(":")
    circuit = {"chain": chain, "wide": wide}[kind](int(size))
    import scipy.sparse  # noqa: F401  (imported before timing, as a session would have it)
    t0 = time.process_time()
    circuit.compile()
    total = time.process_time() - t0
    from _machine import machine
    print(f"{case} on {machine()}: compile CPU {total:.2f} s")
    for key, value in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"  {key:24s} {value:6.2f} s")
    print(f"  {'the rest':24s} {total - sum(spent.values()):6.2f} s")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
