"""Calibration of the PVG 32 rig model against the lab's steady measurements (report 4.7.3).

The report tuned its uncertain parameters by hand (table 4.9 -> table 4.14). Here they are
estimated by weighted least squares (:func:`pvgraph.analysis.calibrate`) from the 19 steady
states of appendix B.7, with confidence intervals.

Model of a datum
    Each scenario's tabulated values (Q_total, Q_branch, Pf, Pm, Pb) are compared with the
    *steady state* of the rig in the scenario's final configuration (L2 as it is after the
    step), solved by :func:`pvgraph.analysis.steady_state` rather than by simulating 8-10 s.
    The steady state is what the lab tabulated, it is about 3x cheaper than a simulation, and
    it is deterministic to ~1e-9, which the finite-difference Jacobian needs. Scenarios sharing
    a configuration (tests 1 and 3, 4 and 6, ...) share one solve; every solve is warm-started
    from the previous one of the same configuration.
Data used
    All solenoid-step tests and the voltage sweep except its two neutral points (sweep-1/2,
    6 V): there the measured 8-9 bar are pressure trapped behind a closed spool, which a model
    with a neutral LS drain cannot produce (docs/pvg32_model.md), so they would bias the fit.
    Q_branch is used only where L2 is open (with L2 closed it is 0 in both).
Weights
    First the rig's stated accuracy (B.7): 1 bar for pressures, 1 L/min for flows. The model
    then misses Pf by about 2.4 bar rms, far beyond the gauge accuracy: that is model error,
    and weighting it like measurement error lets Pf pull on parameters the flows determine (a
    pump flow below the 16.3 L/min the pump was measured to deliver when saturated). So a
    second pass weights each quantity by the larger of its accuracy and the first fit's rms
    error in it (a two-step feasible generalised least squares). The covariance is scaled by
    the reduced chi-square, since how well the model can match the rig is part of the
    uncertainty.
What steady data can and cannot determine
    The supply voltage (through the spool position's dependence on U_in / U_s), the pump flow
    (the saturated sweep points and the relief margin), the return line and the load
    constants. The friction coefficients of table 4.14 act only while spools move; at a steady
    state their force is zero, so the fit reports them as not identifiable if asked for them.
    The report tuned them on its dynamic traces, which are not transcribed.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from pvgraph.analysis import FitParameter, calibrate, steady_state
from pvgraph.analysis.calibrate import CalibrationResult
from pvgraph.errors import ParameterError
from pvgraph.units import lpm, lpm_per_bar, to_bar, to_lpm

from .lab_data import FLOW_ACCURACY, PRESSURE_ACCURACY
from .pvg32.parameters import (PVG32Params, parameter_field, report_initial, report_tuned,
                               with_values)
from .rig import build_rig, laminar_load
from .scenarios import Scenario, all_scenarios

__all__ = ["FIT_PARAMETERS", "DEFAULT_FIT", "TABLE_4_14", "REPORT_SOURCES", "report_table",
           "fit_parameter", "calibration_data", "residual_summary",
           "RigSteadyModel", "calibrate_rig"]

EXCLUDED = ("sweep-1", "sweep-2")         # neutral spool: trapped pressure (see module doc)
QUANTITIES = ("Q_total", "Q_branch", "Pf", "Pm", "Pb")
STEADY_TOL = 1e-10
# Stop when an iteration lowers the cost by less than 1e-3 of it. Near the optimum the cost
# rises by about 2 s^2 (~4 here) at the edge of a 95 % interval, so stopping 0.06 above the
# minimum leaves an estimate within about 0.1 of a half-width of it, and saves half the solves.
FTOL = 1e-3


def _lpm_per_bar(v):
    return v / lpm_per_bar(1.0)


#: Parameters that can be fitted: path -> (lower, upper, display unit, SI -> display)
FIT_PARAMETERS = {
    "rig.supply_voltage": (9.0, 14.0, "V", None),
    "rig.pump_flow": (lpm(13.0), lpm(20.0), "L/min", to_lpm),
    "rig.return_line_K": (lpm_per_bar(1.0), lpm_per_bar(50.0), "L/(min bar)", _lpm_per_bar),
    "rig.L1.laminar_small": (lpm_per_bar(0.05), lpm_per_bar(1.0), "L/(min bar)", _lpm_per_bar),
    "rig.L1.laminar_large": (lpm_per_bar(0.05), lpm_per_bar(1.0), "L/(min bar)", _lpm_per_bar),
    "rig.L3.laminar_small": (lpm_per_bar(0.05), lpm_per_bar(1.0), "L/(min bar)", _lpm_per_bar),
    "rig.L3.laminar_large": (lpm_per_bar(0.05), lpm_per_bar(1.0), "L/(min bar)", _lpm_per_bar),
    "rig.L2.laminar_open": (lpm_per_bar(0.3), lpm_per_bar(10.0), "L/(min bar)", _lpm_per_bar),
    "pvp.viscous_friction": (1e2, 1e6, "N s/m", None),
    "compensator.viscous_friction": (1e2, 1e6, "N s/m", None),
    "compensator.coulomb_friction": (0.0, 500.0, "N", None),
}

#: The default fit: the uncertain rig quantities the steady data determine.
DEFAULT_FIT = ("rig.supply_voltage", "rig.pump_flow", "rig.return_line_K",
               "rig.L1.laminar_small", "rig.L1.laminar_large",
               "rig.L3.laminar_small", "rig.L3.laminar_large")

#: The report's values, SI: its hand-tuned parameters (table 4.14) and its load constants
#: (table 4.8); :data:`REPORT_SOURCES` names the table of each.
TABLE_4_14 = {
    "rig.supply_voltage": 11.5,
    "rig.pump_flow": lpm(16.3),
    "pvp.viscous_friction": 35000.0,
    "compensator.viscous_friction": 20000.0,
    "compensator.coulomb_friction": 50.0,
    "rig.L1.laminar_small": lpm_per_bar(0.2105),
    "rig.L1.laminar_large": lpm_per_bar(0.3544),
    "rig.L3.laminar_small": lpm_per_bar(0.2203),
    "rig.L3.laminar_large": lpm_per_bar(0.4533),
    "rig.L2.laminar_open": lpm_per_bar(1.6111),
}

#: The report table each value of :data:`TABLE_4_14` comes from.
REPORT_SOURCES = {name: ("table 4.8" if name.startswith(("rig.L1.", "rig.L2.", "rig.L3."))
                         else "table 4.14") for name in TABLE_4_14}


def report_table(result) -> str:
    """``result.table`` beside the report's values, each row naming its report table."""
    lines = result.table(TABLE_4_14, "report").splitlines()
    width = len(lines[0])
    out = [lines[0] + "  source", "-" * (width + 12)]
    for line in lines[2:]:
        name = line.split(" ", 1)[0]
        if name in REPORT_SOURCES or name in FIT_PARAMETERS:
            line = f"{line:{width}s}  {REPORT_SOURCES.get(name, '-')}"
        out.append(line)
    return "\n".join(out)


def fit_parameter(path: str, start: PVG32Params) -> FitParameter:
    """The :class:`FitParameter` for ``path``, starting from its value in ``start``."""
    if path not in FIT_PARAMETERS:
        import difflib
        close = difflib.get_close_matches(path, FIT_PARAMETERS, n=3, cutoff=0.5)
        hint = f" Did you mean {' or '.join(map(repr, close))}?" if close else ""
        raise ParameterError(f"{path!r} cannot be calibrated.{hint} Calibratable: "
                             f"{', '.join(FIT_PARAMETERS)}")
    lo, hi, unit, shown = FIT_PARAMETERS[path]
    initial, _ = parameter_field(start, path)
    if initial is None:
        raise ParameterError(f"{path} is None in the start parameters; give it a value first")
    return FitParameter(path, float(min(max(initial, lo), hi)), lo, hi, unit=unit, display=shown)


@dataclass(frozen=True)
class Datum:
    scenario: str
    quantity: str
    value: float        # display units (bar, L/min)
    sigma: float

    @property
    def label(self) -> str:
        return f"{self.scenario}:{self.quantity}"


def calibration_data(scenarios: list[Scenario] | None = None) -> list[Datum]:
    """The measured values used by the fit, in bar and L/min, with their sigmas."""
    scenarios = scenarios if scenarios is not None else \
        [s for s in all_scenarios() if s.name not in EXCLUDED]
    data = []
    for s in scenarios:
        for q in QUANTITIES:
            if q == "Q_branch" and not s.l2_open_finally:
                continue
            value = getattr(s.measured, q)
            if q.startswith("Q"):
                data.append(Datum(s.name, q, to_lpm(value), to_lpm(FLOW_ACCURACY)))
            else:
                data.append(Datum(s.name, q, to_bar(value), to_bar(PRESSURE_ACCURACY)))
    return data


def _config(s: Scenario) -> tuple:
    return (s.U_input, s.orifice_L1 or "small", s.orifice_L3, s.l2_open_finally)


def _rig_circuit(p: PVG32Params, cfg: tuple):
    U, L1, L3, l2 = cfg
    load = laminar_load(p, L1=L1, L3=L3, l2_open=l2, t_switch=None)
    return build_rig(p, load=load, U_input=U)


_OUTPUTS = {"Q_total": ("load.L2.q", "load.L3.q"), "Q_branch": ("load.L2.q",),
            "Pf": ("load.f.port.p",), "Pm": ("load.m.port.p",), "Pb": ("load.b.port.p",)}


def _values(op) -> dict:
    q2, q3 = op["load.L2.q"], op["load.L3.q"]
    return {"Q_total": to_lpm(q2 + q3), "Q_branch": to_lpm(q2),
            "Pf": to_bar(op["load.f.port.p"]), "Pm": to_bar(op["load.m.port.p"]),
            "Pb": to_bar(op["load.b.port.p"])}


def _display_gain(quantity: str) -> float:
    return to_lpm(1.0) if quantity.startswith("Q") else to_bar(1.0)


def _solve_config(args):
    """Steady values of one rig configuration; returns (values in bar/(L/min), y)."""
    p, cfg, y0 = args
    system = _rig_circuit(p, cfg).compile()
    start = y0 if y0 is not None and len(y0) == system.n else None
    op = steady_state(system, y0=start, tol=STEADY_TOL)
    return _values(op), op.y


class RigSteadyModel:
    """``predict(theta)`` for :func:`calibrate`: the steady states of the scenarios' rigs.

    Parameters not fitted are taken from ``base``. Each rig configuration is compiled once; an
    evaluation builds the rig with the new values (milliseconds), reads its runtime parameters
    into the compiled system (:meth:`pvgraph.System.params_from`) and solves the steady state.
    A configuration is compiled again only if a fitted parameter changes its structure.
    :meth:`jacobian` gives d predict / d theta from steady-state sensitivities: one
    factorisation of the steady Jacobian per configuration, with the parameter derivative
    dF/dp of the compiled system. ``workers`` is accepted for compatibility; the compiled
    model runs in this process.
    """

    #: relative step of the (cheap, exact for linear maps) derivative of the rig's component
    #: parameters with respect to the fitted PVG 32 parameters
    MAP_STEP = 1e-6

    def __init__(self, base: PVG32Params, data: list[Datum], *, workers: int = 1):
        from .scenarios import get_scenario
        self.base, self.data = base, data
        self.scenarios = {d.scenario: get_scenario(d.scenario) for d in data}
        self.configs = sorted({_config(s) for s in self.scenarios.values()}, key=str)
        self.warm: dict[tuple, np.ndarray] = {}
        self.workers = workers
        self.evaluations = 0
        self.compilations = 0
        self._compiled: list = []   # compiled systems, one per structure met
        self._last = None   # (theta items, {cfg: OperatingPoint})
        self._maps: dict = {}     # (load, compiled) -> (theta, map)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None

    def params(self, theta: dict) -> PVG32Params:
        return with_values(self.base, theta)

    def _system(self, cfg, circuit):
        """A compiled system of ``circuit``'s structure, carrying its parameter values.

        The configurations differ in runtime parameters (input voltage, load constants) and in
        L2's state: two structures, two compilations for every rig configuration.
        """
        for compiled in self._compiled:
            try:
                values = compiled.params_from(circuit)
            except ParameterError:
                continue   # another structure
            return compiled.with_params(values)
        compiled = circuit.compile()
        self.compilations += 1
        self._compiled.append(compiled)
        return compiled

    def _operating_points(self, theta: dict) -> dict:
        key = tuple(sorted(theta.items()))
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        p = self.params(theta)
        ops = {}
        for cfg in self.configs:
            system = self._system(cfg, _rig_circuit(p, cfg))
            op = steady_state(system, y0=self._start(cfg, system), tol=STEADY_TOL)
            self.warm[cfg] = op.y
            ops[cfg] = op
        self._last = (key, ops)
        return ops

    def _start(self, cfg, system):
        """Warm start: this configuration's last steady state, else the nearest solved one of
        the same structure (same L2 state), else the system's start values."""
        y0 = self.warm.get(cfg)
        if y0 is not None and len(y0) == system.n:
            return y0
        near = [c for c in self.warm if c[3] == cfg[3] and len(self.warm[c]) == system.n]
        if near:
            best = min(near, key=lambda c: (abs(c[0] - cfg[0]), c[1:] != cfg[1:]))
            return self.warm[best]
        return None

    def steady(self, p: PVG32Params) -> dict:
        """Steady values of every configuration at the parameters ``p``."""
        out = {}
        for cfg in self.configs:
            system = self._system(cfg, _rig_circuit(p, cfg))
            op = steady_state(system, y0=self._start(cfg, system), tol=STEADY_TOL)
            self.warm[cfg] = op.y
            out[cfg] = _values(op)
        return out

    def __call__(self, theta: dict) -> np.ndarray:
        self.evaluations += 1
        ops = self._operating_points(theta)
        by_cfg = {cfg: _values(op) for cfg, op in ops.items()}
        return np.array([by_cfg[_config(self.scenarios[d.scenario])][d.quantity]
                         for d in self.data])

    def jacobian(self, theta: dict) -> np.ndarray:
        """d predict / d theta at ``theta`` (display units per SI unit of each parameter)."""
        ops = self._operating_points(theta)
        names = list(theta)
        p = self.params(theta)
        rows = {}
        for cfg, op in ops.items():
            rows[cfg] = self._config_jacobian(cfg, op, p, theta, names)
        J = np.empty((len(self.data), len(names)))
        for i, d in enumerate(self.data):
            J[i] = rows[_config(self.scenarios[d.scenario])][d.quantity]
        return J

    def _parameter_map(self, cfg, compiled, theta, names):
        """How the compiled system's parameters move with theta: per fitted parameter either
        ``("scalar", {name: d value / d theta})`` or ``("table", up values, down values, h)``.

        From differences of the rig build, which is cheap. The rig's scalar component
        parameters are linear in the fitted ones (a load constant, the pump flow, the supply
        voltage of the PVE), so their slopes are kept from the first theta; a fitted parameter
        that moves a table (the supply voltage reshapes the A_H fit) is differenced at every
        theta. The input voltage does not depend on theta, so configurations that differ in it
        alone share one map.
        """
        group = (cfg[1:], id(compiled))
        theta_key = tuple(sorted(theta.items()))
        cached = self._maps.get(group)
        if cached is not None and (cached[0] == theta_key or
                                   all(e[0] == "scalar" for e in cached[1])):
            return cached[1]
        base = compiled.parameters

        def full(values, nm):
            return values.get(nm, base[nm].value)

        def build(th):
            return compiled.params_from(_rig_circuit(self.params(th), cfg))

        here = build(theta)
        out = []
        for k, name in enumerate(names):
            if cached is not None and cached[1][k][0] == "scalar":
                out.append(cached[1][k])
                continue
            h = self.MAP_STEP * max(abs(theta[name]), 1e-300)
            there = build({**theta, name: theta[name] + h})
            changed = {nm for nm in set(here) | set(there)
                       if full(there, nm) != full(here, nm)}
            if all(isinstance(base[nm].value, float) for nm in changed):
                out.append(("scalar", {nm: (full(there, nm) - full(here, nm)) / h
                                       for nm in changed}))
                continue
            back = build({**theta, name: theta[name] - h})
            out.append(("table", there, back, h))
        self._maps[group] = (theta_key, out)
        return out

    def _config_jacobian(self, cfg, op, p, theta, names) -> dict:
        """{quantity: d value / d theta} of one configuration."""
        system = op.system
        compiled = next(c for c in self._compiled if c._lazy is system._lazy)
        outputs = sorted({o for outs in _OUTPUTS.values() for o in outs})
        dF = np.zeros((system.n, len(names)))
        dout = np.zeros((len(outputs), len(names)))
        scalar_cols: dict[str, np.ndarray] = {}
        maps = self._parameter_map(cfg, compiled, theta, names)
        for k, (name, entry) in enumerate(zip(names, maps)):
            if entry[0] == "scalar":
                for nm, slope in entry[1].items():
                    scalar_cols.setdefault(nm, np.zeros(len(names)))[k] = slope
                continue
            _, there, back, h = entry
            U = {"U_input.k": system.parameters["U_input.k"].value}
            # a table changes with this parameter: central differences of the residual and the
            # outputs at the fixed steady state (no solve involved)
            up = compiled.with_params({**there, **U})
            down = compiled.with_params({**back, **U})
            dF[:, k] = (up.residual(op.t, op.y, op.yp)
                        - down.residual(op.t, op.y, op.yp)) / (2 * h)
            op_up = type(op)(op.y, op.yp, up, op.t)
            op_down = type(op)(op.y, op.yp, down, op.t)
            dout[:, k] = [(op_up[o] - op_down[o]) / (2 * h) for o in outputs]
        if scalar_cols:
            pnames = list(scalar_cols)
            D = np.array([scalar_cols[nm] for nm in pnames])          # (n_p, n_theta)
            dF += system.parameter_jacobian(op.t, op.y, op.yp, pnames) @ D
            for j, o in enumerate(outputs):
                _, gp = system.output_gradient(o, op.t, op.y, op.yp, pnames)
                dout[j] += gp @ D
        S = op.solve_linear(-dF)                                      # dy/dtheta
        for j, o in enumerate(outputs):
            gy, _ = system.output_gradient(o, op.t, op.y, op.yp, [])
            dout[j] += gy @ S
        by_name = dict(zip(outputs, dout))
        return {q: _display_gain(q) * sum(by_name[o] for o in outs)
                for q, outs in _OUTPUTS.items()}


def calibrate_rig(fit=DEFAULT_FIT, *, start: PVG32Params | None = None,
                  scenarios: list[Scenario] | None = None, workers: int = 2,
                  reweight: bool = True, progress=None) -> tuple[CalibrationResult, PVG32Params]:
    """Estimate ``fit`` (dotted parameter paths) from the lab's steady data.

    Parameters
    ----------
    fit : sequence of str
        Parameters to estimate, from :data:`FIT_PARAMETERS`.
    start : PVG32Params
        Start values and every parameter not fitted. Default: the report's tuned preset with the
        fitted parameters reset to the untuned values of table 4.9 (12 V, 17 L/min), so the
        estimate is compared with table 4.14 from an independent start.
    scenarios : list of Scenario, optional
        Default: all but the neutral sweep points (module doc).
    reweight : bool
        Refit once with each quantity's sigma raised to the model's rms error in it (module
        doc, "Weights").

    Returns
    -------
    (CalibrationResult, PVG32Params)
        The estimates with intervals, and the tuned parameters with the estimates applied.
    """
    if start is None:
        initial = report_initial()
        start = with_values(report_tuned(), {"rig.supply_voltage": initial.rig.supply_voltage,
                                             "rig.pump_flow": initial.rig.pump_flow})
        start = opening_follows_supply(start)
    fit = list(fit)
    params = [fit_parameter(path, start) for path in fit]
    data = calibration_data(scenarios)
    sigma = np.array([d.sigma for d in data])
    with RigSteadyModel(start, data, workers=workers) as model:
        def run(params, sigma):
            return calibrate(model, [d.value for d in data], params, sigma=sigma,
                             labels=[d.label for d in data], ftol=FTOL, progress=progress)
        result = run(params, sigma)
        first_params = params
        if reweight:
            # second pass: each quantity weighted by the larger of the rig's accuracy and the
            # model's own rms error in it, so that a quantity the model cannot match (Pf) does
            # not drag parameters that other quantities pin down (the pump flow)
            sigma = _group_sigma(result, data)
            params = [dataclasses.replace(p, initial=float(np.clip(v, p.lower, p.upper)))
                      for p, v in zip(params, result.estimates)]
            second = run(params, sigma)
            second.nfev += result.nfev
            second.wall_time += result.wall_time
            second.parameters = first_params
            second.predicted_initial = result.predicted_initial
            second.cost_initial = 0.5 * float(np.sum((result.residuals_initial / sigma) ** 2))
            result = second
    fitted = with_values(start, dict(zip(result.names, result.estimates.tolist())))
    return result, fitted


def opening_follows_supply(p: PVG32Params) -> PVG32Params:
    """``p`` with A_H re-derived from the lab flows at whatever supply voltage it is given
    (``main_spool.opening_shape = None``), as the report identified U_s (4.7.3). With the
    presets' fixed shape a fitted U_s would have to carry the flows alone and drags the pump
    flow towards saturation, where the steady states stop converging."""
    return p.model_copy(update={"main_spool": p.main_spool.model_copy(
        update={"opening_shape": None})})


def _group_sigma(result: CalibrationResult, data: list[Datum]) -> np.ndarray:
    sigma = np.array([d.sigma for d in data])
    for q in QUANTITIES:
        idx = [k for k, d in enumerate(data) if d.quantity == q]
        if idx:
            rms = math.sqrt(np.mean(result.residuals[idx] ** 2))
            sigma[idx] = np.maximum(sigma[idx], rms)
    return sigma


def residual_summary(result: CalibrationResult) -> str:
    """Per-quantity rms of (predicted - measured) before and after the fit."""
    lines = [f"{'quantity':9s} {'n':>3s} {'rms before':>11s} {'rms after':>10s}"]
    for q in QUANTITIES:
        idx = [k for k, lab in enumerate(result.labels) if lab.endswith(":" + q)]
        if not idx:
            continue
        unit = "L/min" if q.startswith("Q") else "bar"
        before = math.sqrt(np.mean(result.residuals_initial[idx] ** 2))
        after = math.sqrt(np.mean(result.residuals[idx] ** 2))
        lines.append(f"{q:9s} {len(idx):3d} {before:8.2f} {unit:5s} {after:6.2f} {unit}")
    return "\n".join(lines)
