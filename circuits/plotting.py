"""The PVG 32 validation figures: steady flow against voltage, held-out errors of the
cross-validation, pressure traces after the steps, model variants side by side.

The first and third take the :class:`~pvgraph.circuits.validation.ScenarioResult` list of
:func:`pvgraph.circuits.validation.validate` and write a PNG (matplotlib, Agg backend).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from pvgraph.plotting import _save
from pvgraph.units import to_bar, to_lpm

__all__ = ["plot_flow_vs_voltage", "plot_cross_validation", "plot_step_traces",
           "plot_step_comparison"]


_ROLE_STYLE = {"fit": ("C1", "fitted"), "held-out": ("C3", "held-out"),
               "trivial": ("0.5", "trivial")}


def plot_flow_vs_voltage(results, path, *, roles=None):
    """Steady total flow against the input voltage, measured and simulated (report fig. 4.39).

    ``roles`` maps ``(scenario, quantity)`` to "fit" / "held-out" / "trivial": the simulated
    points are coloured by the role of their flow.
    """
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for kind, marker, label in (("voltage_sweep", "o", "voltage sweep"),
                                ("solenoid_step", "s", "solenoid-step tests")):
        rs = [r for r in results if r.scenario.kind == kind and not r.error]
        if not rs:
            continue
        u = [r.scenario.U_input for r in rs]
        ax.plot(u, [to_lpm(r.scenario.measured.Q_total) for r in rs], marker, mfc="none",
                color="C0", label=f"measured, {label}")
        groups: dict[str, list] = {}
        for r in rs:
            role = roles.get((r.name, "Q_total"), "held-out") if roles else "held-out"
            groups.setdefault(role, []).append(r)
        for role, members in groups.items():
            color, text = _ROLE_STYLE[role]
            ax.plot([r.scenario.U_input for r in members],
                    [to_lpm(r.simulated["Q_total"]) for r in members], marker, ms=4,
                    color=color, label=f"pvgraph, {label}" + (f" ({text})" if roles else ""))
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


def plot_cross_validation(records, path):
    """Held-out errors of a leave-one-group-out cross-validation, one row per grouping.

    ``records``: ``{grouping, scenario, quantity, error, role, ...}`` dicts (bar, L/min). Left:
    flow error against scenario with the +-1 L/min band; right: Pf, Pm, Pb errors with the
    +-2 bar band. Held-out values are filled, fitted ones hollow, trivial ones grey.
    """
    groupings = list(dict.fromkeys(r["grouping"] for r in records))
    fig, axes = plt.subplots(len(groupings), 2, figsize=(11, 3.3 * len(groupings)),
                             squeeze=False)
    for row, g in zip(axes, groupings):
        recs = [r for r in records if r["grouping"] == g and r["error"] is not None]
        names = list(dict.fromkeys(r["scenario"] for r in recs))
        pos = {n: k for k, n in enumerate(names)}
        for ax, quantities, band, unit in ((row[0], ("Q_total",), 1.0, "L/min"),
                                           (row[1], ("Pf", "Pm", "Pb"), 2.0, "bar")):
            ax.axhspan(-band, band, color="C2", alpha=0.12, label=f"+-{band:g} {unit}")
            for k, q in enumerate(quantities):
                for role in ("held-out", "fit", "trivial"):
                    pts = [r for r in recs if r["quantity"] == q and r["role"] == role]
                    if not pts:
                        continue
                    color = "0.5" if role == "trivial" else f"C{3 + k}"
                    ax.plot([pos[r["scenario"]] + 0.15 * (k - 1) for r in pts],
                            [r["error"] for r in pts], "o", color=color,
                            mfc=color if role == "held-out" else "none",
                            label=f"{q} {role}")
            ax.set_xticks(range(len(names)))
            ax.set_xticklabels(names, rotation=60, fontsize=7)
            ax.set_ylabel(f"predicted - measured [{unit}]")
            ax.set_title(f"leave one {g} group out", fontsize=9)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=6, ncol=2)
    fig.suptitle("PVG 32 cross-validation: held-out errors (filled), fitted (hollow)",
                 fontsize=10)
    return _save(fig, path)


def plot_step_comparison(traces, path, *, title="Step responses"):
    """Pressure drop over L3 after the solenoid step for model variants, one panel per test.

    ``traces``: ``{test: {label: ScenarioResult}}``; the measured steady value is dashed. Each
    label's legend entry gives its worst deviation from the final value 0.5 s after the step.
    """
    tests = list(traces)
    rows = int(np.ceil(len(tests) / 2))
    fig, axes = plt.subplots(rows, 2, figsize=(9, 2.4 * rows + 0.6), sharex=True, squeeze=False)
    for ax, test in zip(axes.flat, tests):
        for k, (label, r) in enumerate(traces[test].items()):
            if r.error:
                continue
            ax.plot(r.trace_t, to_bar(r.trace_dp_L3), color=f"C{3 + k}",
                    label=f"{label}: {to_bar(r.settle_deviation):.2f} bar after 0.5 s")
        s = next(iter(traces[test].values())).scenario
        ax.axhline(to_bar(s.measured.Pf - s.measured.Pb), color="C0", ls="--", lw=1)
        ax.set_title(f"{test}: L2 {s.solenoid_event}", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=6)
    for ax in axes.flat[len(tests):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("time after the step [s]")
    for ax in axes[:, 0]:
        ax.set_ylabel("Pf - Pb [bar]")
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)
