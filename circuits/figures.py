"""Figures of docs/pvg32_model.md that compare model variants on the solenoid-step tests.

``python -m circuits.figures`` regenerates them (about a minute): the pressure drop over L3
after the L2 step (report figures 4.41-4.48) for

- ``lever_mass_steps.png``: the report's lever-equivalent mass 1.569 kg (eq 4.82, kept)
  against the physical 0.157 kg (I / r^2 with the report's own inertia).
"""

from __future__ import annotations

import os
import sys

from pvgraph.circuits.plotting import plot_step_comparison

from .pvg32.parameters import report_tuned, with_values
from .validation import run_scenario

__all__ = ["variant_traces", "lever_mass_figure"]

TESTS = ("test-2", "test-3", "test-8", "test-9")


def variant_traces(variants: dict, tests=TESTS) -> dict:
    """``{test: {label: ScenarioResult}}`` for parameter ``variants`` ``{label: params}``."""
    return {t: {label: run_scenario(t, p) for label, p in variants.items()} for t in tests}


def lever_mass_figure(path: str) -> str:
    p = report_tuned()
    light = with_values(p, {"main_spool.lever_equivalent_mass": 0.157})
    return plot_step_comparison(
        variant_traces({"lever 1.569 kg (report)": p, "lever 0.157 kg (I/r^2)": light}), path,
        title="Main-spool lever mass: dp over L3 after the L2 step")


if __name__ == "__main__":
    folder = sys.argv[1] if len(sys.argv) > 1 else os.path.join("docs", "img")
    for make, name in ((lever_mass_figure, "lever_mass_steps.png"),):
        print("wrote", make(os.path.join(folder, name)))
