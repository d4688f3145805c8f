"""The PVG 32 validation figures: steady flow against voltage, pressure traces after the steps.

Both take the :class:`~circuits.validation.ScenarioResult` list of
:func:`pvgraph.circuits.validation.validate` and write a PNG (matplotlib, Agg backend).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from pvgraph.plotting import _save
from pvgraph.units import to_bar, to_lpm

__all__ = ["plot_flow_vs_voltage", "plot_step_traces"]


def plot_flow_vs_voltage(results, path):
    """Steady total flow against the input voltage, measured and simulated (report fig. 4.39)."""
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for kind, marker, label in (("voltage_sweep", "o", "voltage sweep"),
                                ("solenoid_step", "s", "solenoid-step tests")):
        rs = [r for r in results if r.scenario.kind == kind and not r.error]
        if not rs:
            continue
        u = [r.scenario.U_input for r in rs]
        ax.plot(u, [to_lpm(r.scenario.measured.Q_total) for r in rs], marker, mfc="none",
                color="C0", label=f"measured, {label}")
        ax.plot(u, [to_lpm(r.simulated["Q_total"]) for r in rs], marker, ms=4, color="C3",
                label=f"pvgraph, {label}")
    ax.set_xlabel("PVE input voltage U [V]")
    ax.set_ylabel("total flow Q_v [L/min]")
    ax.set_title("PVG 32 steady flow vs input voltage (cf. report fig. 4.39)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path)


def plot_step_traces(results, path):
    """Pressure drop over L3 after the solenoid step, 8 dynamic tests (report fig. 4.48)."""
    rs = [r for r in results if r.scenario.solenoid_event in ("opening", "closing")
          and not r.error]
    if not rs:
        fig, ax = plt.subplots()
        ax.text(0.5, 0.5, "no solenoid-step scenario in this run", ha="center")
        return _save(fig, path)
    cols = 2
    rows = int(np.ceil(len(rs) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(9, 2.2 * rows), sharex=True, squeeze=False)
    for ax, r in zip(axes.flat, rs):
        s = r.scenario
        ax.plot(r.trace_t, to_bar(r.trace_dp_L3), color="C3", label="pvgraph Pf - Pb")
        ax.axhline(to_bar(s.measured.Pf - s.measured.Pb), color="C0", ls="--",
                   label="measured steady Pf - Pb")
        ax.set_title(f"{r.name}: L2 {s.solenoid_event}, U = {s.U_input} V", fontsize=9)
        ax.set_ylim(0, 80)
        ax.grid(True, alpha=0.3)
    for ax in axes.flat[len(rs):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time after the step [s]")
    for ax in axes[:, 0]:
        ax.set_ylabel("[bar]")
    fig.suptitle("Pressure drop over L3 after the solenoid step (cf. report fig. 4.48)",
                 fontsize=10)
    return _save(fig, path)
