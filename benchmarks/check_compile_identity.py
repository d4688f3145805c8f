"""The compiled System of this checkout against another's: everything that defines it.

For each case, both trees compile the circuit (in fresh subprocesses) and dump a fingerprint:
unknown names and order, start values, nominal values, units, differential flags, equation
labels, the Jacobian pattern, the generated source (residual, Jacobian, events, derived
parameters, outputs), the alias table, the parameter vector (names, values, structural
reasons, where they are read), event and mode names, and the values of the residual, the
Jacobian, the event functions and dF/dp at a perturbed point. The fingerprints must be equal
bit for bit.

Run: ``python benchmarks/check_compile_identity.py --before TREE [case ...]`` with ``TREE`` an
export of the reference commit (``git archive <commit> | tar -x -C TREE``). Cases: ``chain:N``,
``wide:M`` (see bench_scaling.py), ``rig`` (the PVG 32 on its lab rig), ``machine``; a case
with ``@rows`` appended compiles with ``array_rows=True`` (every repeated row shape as
arrays, also in small circuits).
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, os.environ.get("PVGRAPH_BENCH_TREE", str(HERE.parent)))

DEFAULT = ["chain:40", "wide:30", "rig", "machine", "rig@rows", "machine@rows", "chain:2000",
           "wide:1500"]


def build(case: str):
    case = case.split("@")[0]
    if case == "rig":
        from pvgraph.circuits.pvg32.parameters import report_tuned
        from pvgraph.circuits.rig import build_rig, laminar_load
        p = report_tuned()
        return build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                         U_input=4.24)
    if case == "machine":
        from pvgraph.circuits.machine import build_machine
        return build_machine()
    from bench_scaling import chain, wide
    kind, size = case.split(":")
    return {"wide": wide, "chain": chain}[kind](int(size))


def fingerprint(case: str) -> dict:
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = build(case).compile(**({"array_rows": True} if case.endswith("@rows") else {}))
    rng = np.random.default_rng(1)
    y = s.y0 * (1.0 + 0.01 * rng.standard_normal(s.n)) + 0.001 * rng.standard_normal(s.n)
    yp = 0.01 * rng.standard_normal(s.n)
    out = {
        "names": list(s.names), "y0": s.y0.tolist(), "nominal": s.nominal.tolist(),
        "units": list(s.units), "descriptions": list(s.descriptions),
        "differential": s.differential.tolist(), "equations": list(s.equations),
        "rows": s._rows.tolist(), "cols": s._cols.tolist(), "source": s.source(),
        "aliases": repr(sorted((k, repr(v)) for k, v in s._alias_exprs.items())),
        "parameters": [(k, repr(i.value), i.unit, i.owner, i.field, i.structural,
                        i.in_equations, i.in_starts) for k, i in s.parameters.items()],
        "P": repr(s._P[:s._nbase]), "derived": repr(s._P[s._nbase:]),
        "observed": sorted(s.observed.items()), "modes": list(s.mode_names),
        "mode_start": list(s.mode_start),
        "events": [(p, ev.name, ev.direction, ev.terminal, ev.at_start, ev.action is None)
                   for p, ev in s.event_specs],
        "residual": np.asarray(s.residual(0.1, y, yp)).tolist(),
        "jacobian": np.asarray(s.jacobian_values(0.1, y, yp, 7.0)).tolist(),
        "event_values": np.asarray(s.event_values(0.1, y, yp)).tolist(),
        "dFdp": np.asarray(s.parameter_jacobian(0.1, y, yp)).tolist(),
    }
    return out


def _dump(case, tree, path):
    env = dict(os.environ)
    root = Path(tree).resolve() if tree is not None else HERE.parent
    env["PVGRAPH_BENCH_TREE"] = str(root)
    env["PYTHONPATH"] = str(root)
    out = subprocess.run([sys.executable, __file__, "--one", case, path], env=env,
                         capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{case} on {root}: {out.stderr.strip().splitlines()[-1:]}")
    with open(path, "rb") as f:
        return pickle.load(f)


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (a != a and b != b)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


def main(before, cases):
    total = 0
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            old = _dump(case, before, os.path.join(tmp, "before.pkl"))
            new = _dump(case, None, os.path.join(tmp, "after.pkl"))
            diff = [k for k in old if k not in new or not _same(old[k], new[k])]
            total += len(diff)
            print(f"{case}: {len(new['names'])} unknowns, {len(new['rows'])} Jacobian entries, "
                  f"{len(new['parameters'])} parameters, {len(new['source']) / 1e3:.0f} kB "
                  f"source: {len(diff)} differences{' in ' + ', '.join(diff) if diff else ''}")
    print(f"total: {total} differences")
    return total


if __name__ == "__main__":
    args = sys.argv[1:]
    if args[:1] == ["--one"]:
        with open(args[2], "wb") as f:
            pickle.dump(fingerprint(args[1]), f)
    elif args[:1] == ["--before"]:
        sys.exit(1 if main(args[1], args[2:] or DEFAULT) else 0)
    else:
        sys.exit(__doc__)
