"""Parameter estimation: fit model parameters to measurements by weighted least squares.

Given a model ``predict(theta) -> predictions`` (any callable: a steady state, a simulated
trace, a closed-form law), measurements ``y`` and their standard deviations ``sigma``,
:func:`calibrate` minimises ::

    S(theta) = sum_i ((predict(theta)_i - y_i) / sigma_i)^2

with :func:`scipy.optimize.least_squares` (trust-region reflective, bounds respected) and
reports, at the optimum ``theta*`` with Jacobian ``J`` of the weighted residuals:

- the covariance ``C = s^2 (J^T J)^-1`` with ``s^2 = S(theta*) / (m - n)`` (the sigmas are taken
  as relative weights, as in :func:`scipy.optimize.curve_fit` with ``absolute_sigma=False``), or
  ``C = (J^T J)^-1`` when ``absolute_sigma=True`` (the sigmas are true standard deviations);
- standard errors ``sqrt(C_kk)``, two-sided confidence intervals ``theta*_k +- t_{m-n} sqrt(C_kk)``
  from Student's t (the normal quantile ``z`` with ``absolute_sigma=True``: the scale is known,
  not estimated), and the correlation matrix;
- identifiability: ``J^T J`` is inverted through the singular value decomposition of ``J`` with
  its columns scaled to unit length (so the answer does not depend on the parameters' units or
  start values); a direction whose singular value is below ``rcond`` times the largest is *not
  identifiable from these
  data*, and every parameter with a component along it gets an infinite interval and is named
  in :attr:`CalibrationResult.unidentifiable`, instead of a confident-looking number.

The optimiser works on scaled parameters ``z = theta / scale`` (``scale`` defaults to
``|initial|``), so one finite-difference step ``diff_step`` is relative for every parameter.
Without a Jacobian the model is called once per Jacobian column: it should be deterministic to
much better than ``diff_step`` (a steady state solved to tight tolerance is; a transient at
``rtol=1e-4`` is not). With ``jacobian`` (or a ``predict.jacobian`` method) the derivatives
d predict / d theta come from the model itself, e.g. exact steady-state sensitivities
``dy/dp = -F_y^-1 F_p`` from the compiled parameter derivative
(:meth:`pvgraph.analysis.OperatingPoint.sensitivity`), for the search and for the intervals.

References
----------
Bates, D. M., Watts, D. G., *Nonlinear Regression Analysis and Its Applications*, Wiley 1988,
ch. 2 (linear approximation inference regions).
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from ..errors import PvgraphError

__all__ = ["FitParameter", "CalibrationResult", "CalibrationError", "calibrate"]

RCOND = 1e-4          # relative singular value below which a direction is not identifiable
DIFF_STEP = 1e-4      # forward-difference step of the search, in the scaled parameters
COV_STEP = 1e-3       # central-difference step of the Jacobian used for inference


class CalibrationError(PvgraphError):
    """A calibration problem is set up wrongly, or its model cannot be evaluated."""


@dataclass(frozen=True)
class FitParameter:
    """One parameter to estimate: its name, start value, bounds, scale and display unit.

    ``display`` converts an SI value into the unit of ``unit`` for tables (e.g. ``to_lpm``).
    """

    name: str
    initial: float
    lower: float = -math.inf
    upper: float = math.inf
    scale: float | None = None
    unit: str = ""
    display: Callable[[float], float] | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise CalibrationError(f"FitParameter: name must be a non-empty str, got "
                                   f"{self.name!r}")
        for what, value in (("initial value", self.initial), ("lower bound", self.lower),
                            ("upper bound", self.upper)):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating,
                                                                 np.integer)):
                raise CalibrationError(
                    f"{self.name}: {what} {value!r} must be a number in SI units (the mapping "
                    f"form of calibrate's parameters takes quantities: {{{self.name!r}: "
                    f"'2 mm^2'}})")
        if not (math.isfinite(self.initial)):
            raise CalibrationError(f"{self.name}: initial value {self.initial!r} is not finite")
        if not self.lower < self.upper:
            raise CalibrationError(f"{self.name}: lower bound {self.lower} is not below the "
                                   f"upper bound {self.upper}")
        if not self.lower <= self.initial <= self.upper:
            raise CalibrationError(f"{self.name}: initial value {self.initial:g} lies outside "
                                   f"its bounds [{self.lower:g}, {self.upper:g}]")
        if self.scale is not None and not (isinstance(self.scale, (int, float, np.floating))
                                           and self.scale > 0 and math.isfinite(self.scale)):
            raise CalibrationError(f"{self.name}: scale must be positive, got {self.scale!r}")

    @property
    def unit_scale(self) -> float:
        """The scale of the optimiser variable ``z = theta / unit_scale``."""
        if self.scale is not None:
            return self.scale
        return abs(self.initial) if self.initial != 0.0 else 1.0

    def shown(self, value: float) -> float:
        return self.display(value) if self.display else value


@dataclass
class CalibrationResult:
    """Estimates with confidence intervals, residuals and the fit's diagnostics (SI units)."""

    parameters: list[FitParameter]
    estimates: np.ndarray
    std_errors: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    covariance: np.ndarray
    confidence: float
    labels: list[str]
    measured: np.ndarray
    sigma: np.ndarray
    predicted_initial: np.ndarray
    predicted: np.ndarray
    cost_initial: float
    cost: float
    dof: int
    nfev: int
    success: bool
    message: str
    unidentifiable: list[str] = field(default_factory=list)
    singular_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wall_time: float = 0.0
    njev: int = 0           # model Jacobian evaluations (0: finite differences)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @property
    def residuals(self) -> np.ndarray:
        """Predicted minus measured at the estimate (units of the data)."""
        return self.predicted - self.measured

    @property
    def residuals_initial(self) -> np.ndarray:
        return self.predicted_initial - self.measured

    @property
    def correlation(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.covariance / np.outer(d, d)

    @property
    def rms_weighted(self) -> float:
        """Root mean square of the weighted residuals ``(pred - y) / sigma`` at the estimate."""
        return math.sqrt(2.0 * self.cost / max(len(self.measured), 1))

    def __getitem__(self, name: str) -> float:
        try:
            return float(self.estimates[self.names.index(name)])
        except ValueError:
            raise KeyError(f"no fitted parameter {name!r}; fitted: {self.names}") from None

    def interval(self, name: str) -> tuple[float, float]:
        if name not in self.names:
            raise KeyError(f"no fitted parameter {name!r}; fitted: {self.names}")
        k = self.names.index(name)
        return float(self.ci_low[k]), float(self.ci_high[k])

    def table(self, reference: Mapping[str, float] | None = None,
              reference_label: str = "reference") -> str:
        """A plain-text table of the estimates (display units), optionally beside references.

        ``reference`` maps parameter names to values (SI); it may hold more names than were
        fitted (a fitted name it lacks shows '-'), but not only others.
        """
        if reference is not None:
            if not isinstance(reference, Mapping):
                raise CalibrationError(f"table: reference must be a mapping {{parameter name: "
                                       f"value}}, got {reference!r}")
            if reference and not any(nm in reference for nm in self.names):
                import difflib
                key = next(iter(reference))
                close = difflib.get_close_matches(str(key), self.names, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise KeyError(f"table: the reference names no fitted parameter ({key!r}"
                               f"{hint}, ...); fitted: {self.names}")
        pct = f"{100 * self.confidence:.0f} % interval"
        head = f"{'parameter':28s} {'unit':>10s} {'initial':>10s} {'estimate':>10s} {pct:>23s}"
        if reference:
            head += f" {reference_label:>10s}"
        lines = [head, "-" * len(head)]
        for k, p in enumerate(self.parameters):
            lo, hi = self.ci_low[k], self.ci_high[k]
            if np.isfinite(lo) and np.isfinite(hi):
                ci = f"[{p.shown(lo):9.4g}, {p.shown(hi):9.4g}]"
            elif p.name in self.unidentifiable:
                ci = "not identifiable"
            else:
                ci = "no degree of freedom"
            row = (f"{p.name:28s} {p.unit:>10s} {p.shown(p.initial):10.4g} "
                   f"{p.shown(self.estimates[k]):10.4g} {ci:>23s}")
            if reference:
                ref = reference.get(p.name)
                row += f" {p.shown(ref):10.4g}" if ref is not None else f" {'-':>10s}"
            lines.append(row)
        lines.append(f"weighted residual rms {math.sqrt(2 * self.cost_initial / len(self.measured)):.3g}"
                     f" -> {self.rms_weighted:.3g} over {len(self.measured)} data, "
                     f"{self.dof} degrees of freedom, {self.nfev} model evaluations, "
                     f"{self.wall_time:.1f} s")
        if not self.success:
            lines.append(f"NOT CONVERGED: the search stopped before the optimum ({self.message}); "
                         f"the estimates and intervals are those of where it stopped")
        if self.unidentifiable:
            lines.append("not identifiable from these data: " + ", ".join(self.unidentifiable))
        if self.dof <= 0 and not np.all(np.isfinite(self.ci_low)):
            lines.append("as many data as parameters: the residuals cannot tell the data's "
                         "scatter; give sigma with absolute_sigma=True for intervals")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready summary (SI units)."""
        def num(v):
            v = float(v)
            return v if math.isfinite(v) else None
        return {
            "parameters": [{"name": p.name, "unit": "SI", "initial": p.initial,
                            "estimate": num(self.estimates[k]),
                            "std_error": num(self.std_errors[k]),
                            "ci_low": num(self.ci_low[k]), "ci_high": num(self.ci_high[k])}
                           for k, p in enumerate(self.parameters)],
            "confidence": self.confidence,
            "unidentifiable": list(self.unidentifiable),
            "correlation": [[num(v) for v in row] for row in self.correlation],
            "data": [{"label": lab, "measured": num(m), "sigma": num(s),
                      "predicted_initial": num(p0), "predicted": num(p)}
                     for lab, m, s, p0, p in zip(self.labels, self.measured, self.sigma,
                                                 self.predicted_initial, self.predicted)],
            "cost_initial": self.cost_initial, "cost": self.cost, "dof": self.dof,
            "nfev": self.nfev, "success": self.success, "message": self.message,
        }


def _as_parameters(parameters) -> list[FitParameter]:
    if isinstance(parameters, Mapping):
        out = []
        for name, spec in parameters.items():
            if isinstance(spec, FitParameter):
                out.append(spec)
            else:
                out.append(_from_spec(name, spec))
        parameters = out
    if isinstance(parameters, (str, bytes)):
        parameters = [parameters]
    parameters = list(parameters)
    if not parameters:
        raise CalibrationError("no parameters to fit")
    for p in parameters:
        if not isinstance(p, FitParameter):
            raise CalibrationError(
                f"parameters: give FitParameter objects or a mapping {{name: initial}} or "
                f"{{name: (initial, lower, upper)}}, got {p!r} in {parameters!r}")
    names = [p.name for p in parameters]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise CalibrationError(f"parameters listed twice: {dupes}")
    return parameters


def _from_spec(name, spec) -> FitParameter:
    """A :class:`FitParameter` from ``initial`` or ``(initial, lower, upper)``, each a number
    (SI) or a quantity (``"2 mm^2"``): quantities give the table's unit (their first one)."""
    from ..units import UnitError, _NUMBER, is_quantity, parse_unit, to_unit
    items = tuple(spec) if isinstance(spec, (tuple, list)) else (spec,)
    if len(items) not in (1, 3):
        raise CalibrationError(f"parameter {name!r}: give an initial value or (initial, lower, "
                               f"upper), got {spec!r}")
    unit = next((_NUMBER.match(x).group(2) for x in items
                 if isinstance(x, str) and is_quantity(x) and _NUMBER.match(x).group(2)), "")
    factor = parse_unit(unit)[0] if unit else 1.0
    values = []
    for what, x in zip(("initial value", "lower bound", "upper bound"), items):
        try:     # a plain number is SI, as everywhere in calibrate
            values.append(float(to_unit(x, unit, f"{name} {what}")) * factor
                          if unit and is_quantity(x) else float(to_unit(x, "", f"{name} {what}")))
        except UnitError as exc:
            raise CalibrationError(str(exc)) from None
        except (TypeError, ValueError):
            raise CalibrationError(f"parameter {name!r}: {what} {x!r} is not a number or a "
                                   f"quantity") from None
    if unit:
        return FitParameter(name, *values, unit=unit, display=lambda v, f=factor: v / f)
    return FitParameter(name, *values)


def _check_against(params, system) -> None:
    """Refuse a parameter ``system`` does not have, or a unit of another dimension than its."""
    from ..system import System
    from ..units import kind, parse_unit
    if not isinstance(system, System):
        compile_ = getattr(system, "compile", None)
        if compile_ is None:
            raise CalibrationError(f"system= takes a compiled System or a Circuit, got "
                                   f"{type(system).__name__}")
        system = compile_()
    known = system.parameters
    for p in params:
        info = known.get(p.name)
        if info is None:
            import difflib
            close = difflib.get_close_matches(p.name, list(known), n=3, cutoff=0.6)
            hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
            raise CalibrationError(f"parameter {p.name!r} is not a runtime parameter of "
                                   f"{system.name!r}{hint}")
        if not p.unit or not info.unit:
            continue
        try:
            got, want = parse_unit(p.unit)[1], parse_unit(info.unit)[1]
        except PvgraphError:
            continue
        if got != want:
            raise CalibrationError(
                f"parameter {p.name!r}: its values are given in {p.unit!r} ({kind(got)}), but "
                f"{p.name} is {kind(want)} [{info.unit}]")


def _numbers(values, what, *, ravel=True) -> np.ndarray:
    """``values`` as a float array, or a CalibrationError naming ``what``."""
    if isinstance(values, (str, bytes)):
        raise CalibrationError(f"{what} must be numbers, got {values!r}")
    try:
        out = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise CalibrationError(f"{what} must be numbers, got {values!r}") from None
    return out.ravel() if ravel else out


def _central_jacobian(evaluate, z, f0, lo, hi, step):
    """``d pred / dz`` by central differences (one-sided at a bound)."""
    J = np.empty((f0.size, z.size))
    for k in range(z.size):
        h = step * max(1.0, abs(z[k]))
        up, down = z.copy(), z.copy()
        up[k] = min(z[k] + h, hi[k])
        down[k] = max(z[k] - h, lo[k])
        f_up = f0 if up[k] == z[k] else evaluate(up)
        f_down = f0 if down[k] == z[k] else evaluate(down)
        if f_up is None or f_down is None:
            raise CalibrationError("the model fails next to the optimum; cannot estimate the "
                                   "confidence intervals (try a smaller cov_step)")
        J[:, k] = (f_up - f_down) / (up[k] - down[k])
    return J


def calibrate(predict: Callable[[dict], Sequence[float]], measured: Sequence[float],
              parameters: Sequence[FitParameter] | Mapping, *, sigma=None,
              labels: Sequence[str] | None = None, absolute_sigma: bool = False,
              confidence: float = 0.95, diff_step: float = DIFF_STEP, max_nfev: int | None = None,
              xtol: float = 1e-6, ftol: float = 1e-6, rcond: float = RCOND,
              cov_step: float = COV_STEP,
              progress: Callable[[int, float], None] | None = None,
              jacobian: Callable[[dict], np.ndarray] | None = None,
              system=None) -> CalibrationResult:
    """Fit ``parameters`` so that ``predict(theta)`` matches ``measured`` in weighted least squares.

    Parameters
    ----------
    predict : callable
        ``predict({name: value}) -> array`` of the same length as ``measured``. A prediction
        that fails (raises :class:`~pvgraph.errors.PvgraphError` or returns non-finite values)
        during the search is treated as a very poor fit, so the optimiser backs away from it;
        failing at the initial values raises :class:`CalibrationError`.
    measured : array
        The data.
    parameters : list of FitParameter, or mapping
        ``{name: initial}`` or ``{name: (initial, lower, upper)}`` also accepted: numbers in SI
        units, or quantities (``{"orifice.A": ("2 mm^2", "0.5 mm^2", "8 mm^2")}``), whose
        unit the table then shows.
    sigma : float or array, optional
        Standard deviation of each datum (default 1). Weights are ``1 / sigma``.
    labels : list of str, optional
        A name per datum, for tables and for the messages of bad data.
    absolute_sigma : bool
        ``True``: the sigmas are the data's true standard deviations; ``False`` (default):
        they are relative weights and the covariance is scaled by the reduced chi-square.
    confidence : float
        Level of the two-sided confidence intervals (default 0.95).
    diff_step : float
        Forward-difference step of the search Jacobian in the scaled parameters.
    rcond, cov_step : float
        Identifiability threshold on the singular values of the scaled, weighted Jacobian, and
        the central-difference step used to compute that Jacobian at the optimum.
    progress : callable, optional
        ``progress(nfev, cost)`` after every model evaluation.
    jacobian : callable, optional
        ``jacobian({name: value}) -> (len(measured), len(parameters))`` array of
        d predict / d theta (physical units). Default: ``predict.jacobian`` if the model has
        one, else finite differences.
    system : System or Circuit, optional
        What ``predict`` runs, for checking the parameters before the fit: each name must be
        one of its parameters (close matches are named) and a value given as a quantity must
        have that parameter's dimension (``"2 mm"`` for an area is refused). Without it the
        names and units are the caller's: ``predict`` is a black box.

    Returns
    -------
    CalibrationResult
    """
    from scipy import optimize, stats

    params = _as_parameters(parameters)
    if system is not None:
        _check_against(params, system)
    y = _numbers(measured, "measured")
    m, n = y.size, len(params)
    if isinstance(labels, str):
        labels = [labels]
    labels = list(labels) if labels is not None else [f"datum {i}" for i in range(m)]
    if len(labels) != m:
        raise CalibrationError(f"{len(labels)} labels for {m} measurements")
    bad = [labels[i] for i in np.flatnonzero(~np.isfinite(y))]
    if bad:
        raise CalibrationError(f"measurements are not finite: {bad[:5]}")
    s = _numbers(1.0 if sigma is None else sigma, "sigma", ravel=False)
    if s.ndim > 1 or (s.ndim == 1 and s.size != m):
        raise CalibrationError(f"sigma has {s.size} values for {m} measurements (give one "
                               f"value, or one per measurement: shape ({m},), got {s.shape})")
    s = np.broadcast_to(s, (m,)).copy()
    for what, value in (("diff_step", diff_step), ("cov_step", cov_step)):
        if not (isinstance(value, (int, float)) and 0.0 < value < 1.0):
            raise CalibrationError(f"{what} must lie in (0, 1), got {value!r}")
    if not (isinstance(rcond, (int, float)) and 0.0 <= rcond < 1.0):
        raise CalibrationError(f"rcond must lie in [0, 1), got {rcond!r}")
    if max_nfev is not None and not (isinstance(max_nfev, int) and not isinstance(max_nfev, bool)
                                     and max_nfev >= 1):
        raise CalibrationError(f"max_nfev must be a positive integer, got {max_nfev!r}")
    bad = [labels[i] for i in np.flatnonzero(~(s > 0) | ~np.isfinite(s))]
    if bad:
        raise CalibrationError(f"sigma must be positive and finite; not so for {bad[:5]}")
    if m < n:
        raise CalibrationError(f"{m} measurements cannot determine {n} parameters")
    if not (isinstance(confidence, (int, float)) and 0.0 < confidence < 1.0):
        raise CalibrationError(f"confidence must lie in (0, 1), got {confidence!r}")

    scale = np.array([p.unit_scale for p in params])
    z0 = np.array([p.initial for p in params]) / scale
    lo = np.array([p.lower for p in params]) / scale
    hi = np.array([p.upper for p in params]) / scale
    names = [p.name for p in params]
    counter = {"nfev": 0}

    def evaluate(z, *, strict=False):
        theta = dict(zip(names, (z * scale).tolist()))
        counter["nfev"] += 1
        try:
            raw = predict(theta)
        except PvgraphError as exc:
            if strict:
                given = [p for p in params if p.unit]
                hint = "" if system is not None or not given else (
                    f" (the parameters given as quantities were converted to SI by their own "
                    f"unit: {', '.join(f'{p.name} = {p.initial:g} from {p.unit!r}' for p in given)}"
                    f"; calibrate(..., system=...) checks their dimensions against the "
                    f"circuit's parameters)")
                raise CalibrationError(f"the model fails at the initial parameters: "
                                       f"{exc}{hint}") from exc
            return None
        if raw is None:
            raise CalibrationError(f"predict returned None; it must return {m} predictions "
                                   f"(one per measurement)")
        try:
            pred = np.asarray(raw, dtype=float).ravel()
        except (TypeError, ValueError):
            raise CalibrationError(f"predict returned {raw!r}; it must return {m} numbers "
                                   f"(one per measurement)") from None
        if pred.size != m:
            raise CalibrationError(f"predict returned {pred.size} values for {m} measurements")
        if not np.all(np.isfinite(pred)):
            if strict:
                which = [labels[i] for i in np.flatnonzero(~np.isfinite(pred))][:5]
                raise CalibrationError(f"the model gives non-finite predictions at the initial "
                                       f"parameters for {which}")
            return None
        return pred

    pred0 = evaluate(z0, strict=True)
    r0 = (pred0 - y) / s
    penalty = 1e3 * max(1.0, float(np.max(np.abs(r0))))

    def fun(z):
        pred = evaluate(z)
        r = np.full(m, penalty) if pred is None else (pred - y) / s
        if progress:
            progress(counter["nfev"], 0.5 * float(r @ r))
        return r

    if jacobian is None:
        jacobian = getattr(predict, "jacobian", None)
    counter["njev"] = 0

    def model_jac(z):
        theta = dict(zip(names, (z * scale).tolist()))
        counter["njev"] += 1
        try:
            J = np.asarray(jacobian(theta), dtype=float)
        except PvgraphError:
            return None
        if J.shape != (m, n):
            raise CalibrationError(f"jacobian returned shape {J.shape}, expected {(m, n)}")
        return J * scale[None, :]

    def jac(z):
        J = model_jac(z)
        if J is None or not np.all(np.isfinite(J)):
            return np.zeros((m, n))   # a failed point: its penalty residual is constant
        return J / s[:, None]

    t0 = time.perf_counter()
    res = optimize.least_squares(fun, z0, bounds=(lo, hi), method="trf", x_scale=1.0,
                                 diff_step=diff_step, xtol=xtol, ftol=ftol, gtol=1e-10,
                                 max_nfev=max_nfev,
                                 jac=jac if jacobian is not None else "2-point")
    theta = res.x * scale
    r = np.asarray(res.fun, dtype=float)       # the weighted residuals at the optimum
    if np.all(r == penalty):
        raise CalibrationError(f"the model fails at the optimum {dict(zip(names, theta))}")
    pred = r * s + y
    cost = 0.5 * float(r @ r)
    dof = m - n

    # Inference uses a central-difference Jacobian at the optimum (truncation O(h^2)), not the
    # optimiser's forward differences, so a rank-deficient direction shows as such.
    if jacobian is not None:
        Jz = model_jac(res.x)
        if Jz is None or not np.all(np.isfinite(Jz)):
            raise CalibrationError("the model's jacobian fails at the optimum; cannot estimate "
                                   "the confidence intervals")
        Jz = Jz / s[:, None]
    else:
        Jz = _central_jacobian(evaluate, res.x, pred, lo, hi, cov_step) / s[:, None]
    # identifiability on the Jacobian with its columns scaled to unit norm: a question of the
    # columns' directions, not of the units (an offset started at 0 has the scale 1 SI unit,
    # whose column is tiny, and was read as not identifiable)
    col = np.linalg.norm(Jz, axis=0)
    col = np.where(col > 0.0, col, 1.0)
    _, sv, Vt = np.linalg.svd(Jz / col, full_matrices=False)
    keep = sv > rcond * (sv[0] if sv.size and sv[0] > 0 else 1.0)
    inv = np.where(keep, 1.0 / np.where(keep, sv, 1.0) ** 2, 0.0)
    cov = ((Vt.T * inv) @ Vt) / np.outer(col, col) * np.outer(scale, scale)   # physical
    weak = ((Vt[~keep] ** 2).sum(axis=0) > 1e-3) if np.any(~keep) else np.zeros(n, bool)
    # sigma estimated from the residuals needs a degree of freedom; without one the scatter
    # is unknown and so are the intervals (not sigma = 1)
    s2 = 1.0 if absolute_sigma else (2.0 * cost / dof if dof > 0 else math.inf)
    cov = cov * s2 if math.isfinite(s2) else np.full_like(cov, math.inf)
    cov[weak, :] = np.inf
    cov[:, weak] = np.inf
    std = np.sqrt(np.diag(cov))
    if absolute_sigma:      # known sigmas: the estimate's error is normal, whatever m - n
        tq = float(stats.norm.ppf(0.5 + confidence / 2.0))
    elif dof > 0:           # sigma estimated from the residuals: Student's t
        tq = float(stats.t.ppf(0.5 + confidence / 2.0, dof))
    else:
        tq = math.inf
    half = tq * std
    unident = [names[k] for k in np.flatnonzero(weak)]
    for k, prm in enumerate(params):
        for bound, side in ((prm.lower, "lower"), (prm.upper, "upper")):
            if np.isfinite(bound) and abs(theta[k] - bound) <= 1e-6 * max(abs(bound),
                                                                         scale[k]):
                warnings.warn(f"calibrate: {prm.name} ends on its {side} bound {bound!r}: the "
                              f"data may want it beyond, and its interval (which assumes a free "
                              f"parameter) means little there", UserWarning, stacklevel=2)
    if not res.success:
        warnings.warn(f"calibrate: the search stopped before converging ({res.message}): the "
                      f"estimates and intervals are those of where it stopped, not of the "
                      f"optimum; raise max_nfev or start nearer", UserWarning, stacklevel=2)
    wall = time.perf_counter() - t0
    return CalibrationResult(
        parameters=params, estimates=theta, std_errors=std, ci_low=theta - half,
        ci_high=theta + half, covariance=cov, confidence=confidence, labels=labels,
        measured=y, sigma=s, predicted_initial=pred0, predicted=pred,
        cost_initial=0.5 * float(r0 @ r0), cost=cost, dof=dof, nfev=counter["nfev"],
        success=bool(res.success), message=str(res.message), unidentifiable=unident,
        singular_values=sv, wall_time=wall, njev=counter["njev"])
