"""Hydraulic power and energy balances over a simulation result.

Port flows are positive into a component, so ``sum(p * q)`` over a component's hydraulic ports
is the hydraulic power it absorbs (negative for a pump or flow source delivering power).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Sequence

import numpy as np

__all__ = ["hydraulic_ports", "hydraulic_power", "energy_balance"]


def hydraulic_ports(result, component_path: str) -> list[str]:
    """Names of the hydraulic ports (with both ``p`` and ``q``) of a component."""
    if not isinstance(component_path, str):
        raise TypeError(f"a component is named by its path (str, e.g. 'orifice'), got "
                        f"{component_path!r}")
    prefix = component_path + "."
    names = set(result.system.all_names())
    ports = sorted({nm[len(prefix):-2] for nm in names
                    if nm.startswith(prefix) and nm.endswith(".p")
                    and "." not in nm[len(prefix):-2]})
    ports = [pt for pt in ports if f"{prefix}{pt}.q" in names]
    if not ports:
        import difflib
        hydraulic = sorted({nm.rsplit(".", 2)[0] for nm in names
                            if nm.endswith(".p") and nm.count(".") >= 2
                            and nm[:-2] + ".q" in names})
        if any(nm.startswith(prefix) for nm in names):
            raise KeyError(f"{component_path!r} has no hydraulic ports in this result; the "
                           f"components with hydraulic ports are {hydraulic}")
        close = difflib.get_close_matches(component_path, hydraulic, n=3)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else \
            f"; the components with hydraulic ports are {hydraulic}"
        raise KeyError(f"no component {component_path!r} in this result{hint}")
    return ports


def hydraulic_power(result, component_path: str):
    """Hydraulic power absorbed by a component [W]: the sum of ``p * q`` over its ports.

    ``result`` is a :class:`~pvgraph.simulate.Solution` (gives an array over ``result.t``) or an
    :class:`~pvgraph.analysis.OperatingPoint` (gives a float).
    """
    total = 0.0
    for pt in hydraulic_ports(result, component_path):
        total = total + result[f"{component_path}.{pt}.p"] * result[f"{component_path}.{pt}.q"]
    return total


def energy_balance(solution, pump: str = "pump", *, losses: Sequence[str] = ("orifice",),
                   volumes: Mapping[str, tuple[float, float]] | None = None) -> dict:
    """Power balance of a circuit: delivered = dissipated + rate of stored compressible energy.

    Parameters
    ----------
    pump : component delivering power (its absorbed power, negated).
    losses : components dissipating power (their absorbed power).
    volumes : mapping ``path -> (V, beta)`` of volume nodes (constant bulk modulus); the stored
        energy is ``V p^2 / (2 beta)`` and its rate ``V p p' / beta``.

    Returns a dict of arrays ``t, P_pump, P_loss, E_stored, dE_dt, imbalance``
    (``imbalance = P_pump - P_loss - dE_dt``).
    """
    from ..simulate import _name_list
    losses = _name_list(losses, "energy_balance: losses")
    if volumes is not None and not isinstance(volumes, Mapping):
        raise TypeError(f"energy_balance: volumes must be a mapping {{path: (V [m^3], beta "
                        f"[Pa])}}, got {volumes!r}")
    for path, spec in (volumes or {}).items():
        try:
            if isinstance(spec, (str, bytes)):
                raise TypeError
            V, beta = (float(x) for x in spec)
        except (TypeError, ValueError):
            V = beta = float("nan")
        if not (np.isfinite(V) and np.isfinite(beta) and V > 0.0 and beta > 0.0):
            raise ValueError(f"energy_balance: volumes[{path!r}] must be (V [m^3], beta [Pa]), "
                             f"both positive numbers, got {spec!r}")
    t = solution.t
    P_pump = -hydraulic_power(solution, pump)
    P_loss = sum((hydraulic_power(solution, c) for c in losses), np.zeros(len(t)))
    E = np.zeros(len(t))
    dE = np.zeros(len(t))
    for path, (V, beta) in (volumes or {}).items():
        p = solution[f"{path}.port.p"]
        E = E + V * p * p / (2.0 * beta)
        dE = dE + V * p * solution.der(f"{path}.port.p") / beta
    return {"t": t, "P_pump": P_pump, "P_loss": P_loss, "E_stored": E, "dE_dt": dE,
            "imbalance": P_pump - P_loss - dE}
